"""Counters the GPU alone updates: GPU-side reset and staged read-back, and statistics derived from the allocator."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.gl_state import raw_gl
from guaca_py.gpu_counters import CounterBlock, FencedCopies, StagedReader, UploadBuffer
from guaca_py.reference import layered_quads_scene

SIZE = 64

_ADD = """
#version 450 core
layout(local_size_x = 64) in;
layout(std430, binding = 0) buffer C { uint c[]; };
void main() { atomicAdd(c[gl_GlobalInvocationID.x % 3u], 1u); }
"""


def test_counter_block_resets_and_reads(gl_context):
    block = CounterBlock(gl_context, ("a", "b", "c"))
    add = gl_context.compute_shader(_ADD)
    try:
        for start in (0, 7, 7):  # the same reset twice reuses the uploaded reset values
            block.reset(b=start)
            block.bind(0)
            add.run(3)  # 192 invocations: 64 per counter
            gl_context.memory_barrier()
            assert block.read() == {"a": 64, "b": 64 + start, "c": 64}
        with pytest.raises(KeyError):
            block.reset(nope=1)
    finally:
        block.release()
        add.release()


def test_fenced_copies_give_the_newest_finished_copy(gl_context):
    # a frame loop's late counters: copies queue behind a fence each; the newest finished one is
    # read and the older ones dropped; with every slot waiting, a new copy drops the oldest
    gl = raw_gl()
    if gl is None:
        pytest.skip("no raw GL entry points")
    buf = gl_context.buffer(reserve=8)
    copies = FencedCopies(gl, 8, slots=2)
    try:
        assert copies.newest() is None
        for v in (1, 2, 3):
            buf.write(np.array([v, 10 * v], dtype=np.uint32).tobytes())
            copies.copy(buf, tag=v)
        gl_context.finish()
        data, tag = copies.newest()
        assert tag == 3 and np.frombuffer(data, dtype=np.uint32).tolist() == [3, 30]
        assert copies.newest() is None  # the older copy went with it
        buf.write(np.array([4, 40], dtype=np.uint32).tobytes())
        copies.copy(buf, tag=4)  # not waited for: newest() waits for it, the only one queued
        data, tag = copies.newest()
        assert tag == 4 and np.frombuffer(data, dtype=np.uint32).tolist() == [4, 40]
    finally:
        copies.release()
        buf.release()


@pytest.mark.parametrize("fenced", [True, False])
def test_counters_set_aside_come_back_a_frame_later(gl_context, monkeypatch, fenced):
    # a frame loop's late read: through fenced mapped copies, or a plain buffer read where the
    # raw GL entry points do not load; either way the last stage() and its tag, then a fresh read
    import guaca_py.gpu_counters as gpu_counters

    if not fenced:
        monkeypatch.setattr(gpu_counters, "raw_gl", lambda: None)
    elif raw_gl() is None:
        pytest.skip("no raw GL entry points")
    block = CounterBlock(gl_context, ("a", "b"))
    try:
        block.reset(a=5)
        block.stage("first")
        assert isinstance(block._late[0], FencedCopies) == fenced
        counts, tag, late = block.latest(True)
        assert late and tag == "first" and counts == {"a": 5, "b": 0}
        block.reset(a=7)
        counts, tag, late = block.latest(True)  # nothing set aside since: this frame's, read now
        assert not late and tag is None and counts["a"] == 7
    finally:
        block.release()


def test_counters_set_aside_per_view_come_back_to_that_view(gl_context):
    # render_views() without read-back: each view reads its own counters of the previous call
    block = CounterBlock(gl_context, ("a",))
    try:
        for view, value in ((0, 10), (1, 20)):
            block.reset(a=value)
            block.stage(f"view {view}", view=view)
        counts, tag, late = block.latest(True, view=1)
        assert late and tag == "view 1" and counts == {"a": 20}
        block.reset(a=30)
        assert block.latest(True, view=2) == ({"a": 30}, None, False)  # nothing staged for view 2: read now
        counts, tag, late = block.latest(True, view=0)  # view 2's fresh read left view 0's copy alone
        assert late and tag == "view 0" and counts == {"a": 10}
        block.stage("again", view=1)
        block.read()  # a frame read at once: whatever any view set aside before is older
        assert block.staged(1) is None
    finally:
        block.release()


def test_upload_and_staged_read_round_trip(gl_context):
    up, reader = UploadBuffer(gl_context), StagedReader(gl_context)
    try:
        for n in (5, 300, 40):  # grows once, then reuses the larger buffer
            data = np.arange(n, dtype=np.uint32) * 3 + n
            up.upload(data.tobytes())
            got = np.frombuffer(reader.read(up.buffer, 8, 4 * (n - 2)), dtype=np.uint32)
            assert got.tolist() == data[-2:].tolist()
        assert up.buffer.size >= 300 * 4
    finally:
        up.release()
        reader.release()


def _linked_nodes(method) -> int:
    """Nodes reachable from the list heads, walked on the CPU from the method's link buffer."""
    words = np.frombuffer(method._links.read(), dtype=np.uint64 if method.link_bytes == 8 else np.uint32)
    links = (words & 0xFFFFFFFF).astype(np.int64)
    pixels = method._pixels
    heads = links[:pixels].tolist()
    if method.extra_slots:  # second list heads follow the node links
        heads += links[pixels + method.capacity : 2 * pixels + method.capacity].tolist()
    count = 0
    for n in heads:
        while n:
            count += 1
            n = links[pixels + n]
    return count


@pytest.mark.parametrize(
    ("method", "overrides"),
    [
        ("presort_lf", {}),
        ("presort_lf_et", {"threshold": 0.9}),
        ("presort_lf", {"budget_mb": 0.01}),
        ("presort_lf_et", {"budget_mb": 0.01, "threshold": 0.9}),
        ("post_sort", {}),
        ("presort_lf_merge2_et", {"threshold": 0.9}),
    ],
)
def test_stored_equals_the_nodes_in_the_lists(renderers, method, overrides):
    """stored is derived (allocations minus overflow minus unlinked): it must equal what the lists hold."""
    scene = layered_quads_scene(n_layers=12, order="shuffled", seed=5)
    r = renderers(method, **overrides)
    frame = r.render(scene, SIZE, SIZE)
    fr = frame.stats["fragments"]
    assert fr["stored"] == _linked_nodes(r.method), fr
    if "budget_mb" in overrides:
        assert fr["overflow"] > 0 and fr["stored"] + fr["overflow"] <= fr["nodes_requested"]
    else:
        assert fr["overflow"] == 0
    if overrides.get("threshold") == 0.9 and "budget_mb" not in overrides:
        assert fr["early_termination_culled"] > 0


def test_frame_loop_reads_counters_a_frame_late(renderer_factory):
    """Without read-back the stats are the previous frame's (no wait); an overflow grows the pool for the next."""
    small = layered_quads_scene(n_layers=4, order="shuffled", seed=6, with_opaque=False)
    deep = layered_quads_scene(n_layers=16, order="shuffled", seed=6, with_opaque=False)
    r = renderer_factory("exact", method="presort_lf")
    first = r.render(small, SIZE, SIZE, read_back=False)  # nothing staged yet: read now
    assert "fragments_of" not in first.stats and not first.is_read and first.texture is not None
    want = r.render(small, SIZE, SIZE).stats["fragments"]["stored"]
    r.render(small, SIZE, SIZE, read_back=False)
    late = r.render(deep, SIZE, SIZE, read_back=False)
    assert late.stats["fragments_of"] == "previous frame"
    assert late.stats["fragments"]["stored"] == want  # the small scene's count, not the deep one's
    grown = r.render(deep, SIZE, SIZE, read_back=False)  # reports the deep frame's overflow, grows the pool
    assert grown.stats["fragments"]["overflow"] > 0 and any("previous frame" in w for w in grown.stats["warnings"])
    r.render(deep, SIZE, SIZE, read_back=False)
    settled = r.render(deep, SIZE, SIZE, read_back=False)
    assert settled.stats["fragments"]["overflow"] == 0
    exact = r.render(deep, SIZE, SIZE)
    assert exact.stats["fragments"]["stored"] == settled.stats["fragments"]["stored"]


def test_frame_loop_with_the_compute_rasterizer(renderer_factory):
    """The compute rasterizer's totals are read a frame late too; the counts match a read-back frame's."""
    scene = layered_quads_scene(n_layers=6, order="shuffled", seed=8, with_opaque=False)
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    loop = [r.render(scene, SIZE, SIZE, read_back=False) for _ in range(3)]
    assert loop[-1].stats["fragments_of"] == "previous frame"
    assert loop[-1].stats["raster"]["compute"]["triangles"] == 12
    exact = r.render(scene, SIZE, SIZE)
    assert "fragments_of" not in exact.stats
    assert loop[-1].stats["fragments"]["stored"] == exact.stats["fragments"]["stored"] > 6 * 1000


@pytest.mark.parametrize("method", ["unsorted_blend", "stochastic"])
def test_blending_methods_read_their_sample_counts_a_frame_late(renderer_factory, method):
    """Hardware blending counts fragments with a samples-passed query; reading it mid-frame waited for the GPU."""
    small = layered_quads_scene(n_layers=2, order="shuffled", seed=9, with_opaque=False)
    deep = layered_quads_scene(n_layers=7, order="shuffled", seed=9, with_opaque=False)
    r = renderer_factory("exact", method=method)
    want_small = r.render(small, SIZE, SIZE).stats["fragments"]
    want_deep = r.render(deep, SIZE, SIZE).stats["fragments"]
    assert want_deep["blended"] > want_small["blended"] > 0
    first = r.render(small, SIZE, SIZE, read_back=False)  # nothing pending: its own counts
    assert "fragments_of" not in first.stats and first.stats["fragments"] == want_small
    late = r.render(deep, SIZE, SIZE, read_back=False)
    assert late.stats["fragments_of"] == "previous frame" and late.stats["fragments"] == want_small
    again = r.render(deep, SIZE, SIZE, read_back=False)
    assert again.stats["fragments"] == want_deep
    exact = r.render(small, SIZE, SIZE)  # a read-back frame reads its own
    assert "fragments_of" not in exact.stats and exact.stats["fragments"] == want_small
    if method == "stochastic":
        assert want_deep["depth_pass"] > want_small["depth_pass"] > 0


def test_kbuffer_reads_its_counters_a_frame_late(renderer_factory):
    """The k-buffer's counters follow the A-buffer's pattern: without read-back, the previous frame's."""
    small = layered_quads_scene(n_layers=2, order="shuffled", seed=10, with_opaque=False)
    deep = layered_quads_scene(n_layers=6, order="shuffled", seed=10, with_opaque=False)
    r = renderer_factory("exact", method="kbuffer")
    want_small = r.render(small, SIZE, SIZE).stats["fragments"]
    want_deep = r.render(deep, SIZE, SIZE).stats["fragments"]
    assert want_deep["total"] > want_small["total"] > 0
    r.render(small, SIZE, SIZE, read_back=False)
    late = r.render(deep, SIZE, SIZE, read_back=False)
    assert late.stats["fragments_of"] == "previous frame" and late.stats["fragments"] == want_small
    assert r.render(deep, SIZE, SIZE, read_back=False).stats["fragments"] == want_deep
    assert r.render(deep, SIZE, SIZE).stats["fragments"] == want_deep
