"""The other exact one-pass A-buffer methods against the float64 reference: two merged lists,
critical section (spin lock on devices without interlock), post-sort (fixed array) and post-merge16."""

from __future__ import annotations

import colorsys
import dataclasses

import numpy as np
import pytest
from conftest import quad_node, simple_scene
from exact_frames import ReferenceCache, render_interpenetrating_exactly, render_layered_exactly

from guaca_py.reference import compare, layered_quads_scene

SIZE = 96
METHODS = ["presort_lf_merge2_et", "presort_cs", "presort_cs_et", "post_sort", "post_merge16"]
_REFS = ReferenceCache()


def reference_of(key, scene, w=SIZE, h=SIZE):
    """Reference image, edge exclusion mask and layer counts (cached: several methods share a scene)."""
    return _REFS.of(key, scene, w, h)


def deep_scene(n, alpha, order="shuffled", seed=5, size=10.0):
    """n screen-covering planes between z=2 and z=-3: every pixel has depth complexity n."""
    nodes = [
        quad_node(f"p{i:02d}", 2.0 - 5.0 * i / (n - 1), colorsys.hsv_to_rgb(i / n, 0.8, 0.95), alpha, size=size)
        for i in range(n)
    ]
    if order == "back_to_front":
        nodes = nodes[::-1]
    elif order == "shuffled":
        nodes = [nodes[i] for i in np.random.default_rng(seed).permutation(n)]
    return simple_scene(nodes, background=(0.05, 0.08, 0.12))


def check_common(frame, method):
    """Counters and memory every method reports; nothing lost."""
    s = frame.stats
    fr, mem = s["fragments"], s["memory"]
    assert s["geometry_passes"] == 1 and s["method"] == method
    assert fr["overflow"] == 0 and fr["guard_abandoned"] == 0 and fr["lock_abandoned"] == 0, fr
    assert fr.get("truncated", 0) == 0, fr
    assert fr["stored"] > 0 and mem["abuffer_pool_used"] <= mem["abuffer_pool"]
    return fr, mem


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("order", ["front_to_back", "back_to_front", "shuffled"])
def test_exact_layered_with_opaque(renderers, method, order):
    check_common(render_layered_exactly(_REFS, renderers(method), order, SIZE), method)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("order", ["forward", "reverse", "shuffled"])
def test_exact_interpenetrating(renderers, method, order):
    check_common(render_interpenetrating_exactly(_REFS, renderers(method), order, SIZE), method)


@pytest.mark.parametrize("method", METHODS)
def test_exact_forty_layers(renderers, method):
    # depth complexity 40 everywhere: above post_sort's default array (32) and over two rounds of 16
    scene = deep_scene(40, 0.12)
    ref, mask, layers = reference_of("deep40", scene, 64, 64)
    assert layers.min() == 40
    r = renderers(method, max_fragments=48) if method == "post_sort" else renderers(method)
    frame = r.render(scene, 64, 64)
    err = compare(frame.image, ref, mask)
    assert err["max_abs_255"] <= 2.0, err
    check_common(frame, method)


def test_post_sort_truncates_to_the_nearest(renderers):
    # 12 layers everywhere, an array of 4: exactly 8 fragments per pixel are truncated, the 4 nearest
    # are kept whatever the submission order, so the image is the reference of the 4 nearest planes
    scene = deep_scene(12, 0.35, order="shuffled", seed=9)
    nearest = simple_scene(
        sorted(scene.nodes, key=lambda n: -n.transform.translation[2])[:4], background=scene.background
    )
    ref, mask, _ = reference_of("nearest4", nearest, 64, 64)
    frame = renderers("post_sort", max_fragments=4).render(scene, 64, 64)
    fr = frame.stats["fragments"]
    assert fr["truncated"] == 8 * 64 * 64 and fr["truncated_pixels"] == 64 * 64, fr
    assert any("max_fragments" in w for w in frame.stats["warnings"])
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0
    # the default array (32) on 40 layers: truncation is reported, never silent
    deep = renderers("post_sort").render(deep_scene(40, 0.12), 64, 64)
    assert deep.stats["fragments"]["truncated"] == 8 * 64 * 64
    # post_merge16 has no such limit
    assert renderers("post_merge16").render(deep_scene(40, 0.12), 64, 64).stats["fragments"]["truncated"] == 0


@pytest.mark.parametrize("method", METHODS)
def test_equal_depths_resolve_deterministically(renderers, method):
    # coplanar quads: the first draw is in front at equal depth (tie id), run after run
    a = quad_node("a", 0.0, (1, 0, 0), 0.5)
    b = quad_node("b", 0.0, (0, 0, 1), 0.5)
    r = renderers(method)
    imgs = [r.render(simple_scene(order), 32, 32).image for order in ([a, b], [a, b], [a, b])]
    assert all((i == imgs[0]).all() for i in imgs)
    c = imgs[0][16, 16].astype(int)
    assert c[0] > c[2]


@pytest.mark.parametrize("method", METHODS)
def test_exact_with_coplanar_groups(renderers, method):
    # 7 depths x 3 coplanar planes, shuffled: 21 fragments with equal-depth runs, one of them across
    # post_merge16's round boundary (16); equal depths blend in draw order, as in the reference
    rng = np.random.default_rng(4)
    nodes = [
        quad_node(f"g{i}", 1.5 - 0.6 * (i // 3), tuple(rng.uniform(0.1, 1.0, 3)), 0.1, size=12.0) for i in range(21)
    ]
    scene = simple_scene([nodes[i] for i in rng.permutation(21)], background=(0.05, 0.08, 0.12))
    ref, mask, layers = reference_of("coplanar21", scene, 64, 64)
    assert layers.min() == 21
    frame = renderers(method).render(scene, 64, 64)
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0
    check_common(frame, method)


@pytest.mark.parametrize("method", ["presort_lf_merge2_et", "presort_cs_et"])
def test_early_termination_within_bound(renderer_factory, method):
    # 20 full-screen layers of alpha 0.5 front to back: insertion stops once a list is saturated
    scene = deep_scene(20, 0.5, order="front_to_back", size=12.0)
    ref, mask, _ = reference_of("et20", scene, 64, 64)
    threshold = 0.9
    frame = renderer_factory("exact", method=method, method_overrides={"threshold": threshold}).render(scene, 64, 64)
    fr = frame.stats["fragments"]
    assert fr["early_termination_culled"] > 0 and fr["stored"] < 20 * 64 * 64, fr
    assert compare(frame.image, ref, mask)["max_abs_255"] <= (1.0 - threshold) * 255.0 + 2.0


def test_presort_cs_without_et_stores_everything(renderers):
    scene = deep_scene(20, 0.5, order="front_to_back", size=12.0)
    fr = renderers("presort_cs").render(scene, 64, 64).stats["fragments"]
    assert fr["early_termination_culled"] == 0 and fr["stored"] == 20 * 64 * 64


def test_merge2_uses_both_lists(renderers):
    # twice the list heads, and the composite would miss fragments if either list were left out
    r = renderers("presort_lf_merge2_et")
    frame = r.render(deep_scene(12, 0.3), 64, 64)
    mem = frame.stats["memory"]
    assert mem["abuffer_heads"] == 2 * 64 * 64 * r.method.link_bytes
    assert frame.stats["fragments"]["stored"] == 12 * 64 * 64
    links = np.frombuffer(r.method._links.read(), np.uint32 if r.method.link_bytes == 4 else np.uint64)
    p, cap = 64 * 64, r.method.capacity
    first, second = links[:p], links[p + cap : 2 * p + cap]
    assert (first != 0).all() and (second != 0).all()  # every pixel fills both lists


def test_critical_section_on_this_device(renderer_factory):
    from guaca_py.raster.choice import compute_kernels_draw

    # 'auto' takes the spin lock where compute kernels make the fragments (raster: auto on a GPU),
    # the interlock where the device has it and fragment shaders do, the spin lock otherwise
    r = renderer_factory("exact", method="presort_cs_et")
    frame = r.render(layered_quads_scene(n_layers=16, order="shuffled", seed=2), 64, 64)
    compute = compute_kernels_draw(r.method.settings["raster"], r.caps)
    expected = "interlock" if r.caps.fragment_interlock and not compute else "spin"
    assert frame.stats["critical_section"] == expected
    assert ("abuffer_locks" in frame.stats["memory"]) == (expected == "spin")
    if not r.caps.fragment_interlock:
        from guaca_py.errors import UnsupportedMethodError

        with pytest.raises(UnsupportedMethodError, match="interlock"):
            renderer_factory("exact", method="presort_cs", method_overrides={"lock": "interlock"})


def test_spin_lock_gives_up_counted_when_held(renderer_factory):
    # every pixel's lock held by nobody that will release it: each fragment gives up after max_spin
    # attempts, is counted and reported, and the frame shows what is left (opaque + background)
    r = renderer_factory("exact", method="presort_cs", method_overrides={"lock": "spin", "max_spin": 16})
    m = r.method
    prepare = m.prepare

    def prepare_with_locks_held(frame):
        prepare(frame)
        p = frame.pixel_count
        m._links.write(np.ones(p, np.uint32).tobytes(), offset=(p + m.capacity) * 4)

    m.prepare = prepare_with_locks_held
    scene = layered_quads_scene(n_layers=16, order="shuffled", seed=2)
    frame = r.render(scene, 64, 64)
    fr = frame.stats["fragments"]
    assert fr["stored"] == 0 and fr["lock_abandoned"] > 16 * 64, fr
    assert any("lock" in w for w in frame.stats["warnings"])
    opaque_only = simple_scene(
        [n for n in scene.nodes if n.material.uniforms["alpha"] >= 1.0], background=scene.background
    )
    ref, mask, _ = reference_of("opaque_only", opaque_only, 64, 64)
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_interlock_variant_generates_the_critical_section(renderer_factory):
    # the GPU-only path, checked as generated text (this device may not compile it)
    from guaca_py.methods import method_class

    r = renderer_factory("exact")
    caps = dataclasses.replace(r.caps, fragment_interlock=True)
    m = method_class("presort_cs_et")(dict(r.method.settings, lock="auto", raster="hardware", max_spin=64), caps)
    assert m.lock == "interlock" and m.extra_slots == 0 and "fragment_shader_interlock" in m.extensions()
    gpu = dataclasses.replace(caps, software=False)  # raster: auto on a GPU: compute kernels, the spin lock
    on_gpu = method_class("presort_cs_et")(dict(r.method.settings, lock="auto", max_spin=64), gpu)
    assert on_gpu.lock == "spin" and "spin lock" in on_gpu.auto_compute_reason  # every draw: compute
    assert m.auto_compute_reason is None
    src = r.shaders.render(
        "geometry/triangle_mesh.frag.j2",
        transparent=True,
        material_uniforms="",
        visibility_methods="",
        visibility_calls=[],
        method_extensions=m.extensions(),
        method_fragment_template=m.fragment_template(),
        **m.template_vars(),
    )
    assert "layout(pixel_interlock_ordered) in;" in src and "atomicCompSwap" not in src
    body = src[src.index("void main()") :]
    assert (
        body.index("beginInvocationInterlockARB();")
        < body.index("submit_fragment();")
        < body.index("endInvocationInterlockARB();")
    )
    # helper invocations leave before any insertion or lock loop: their atomics return undefined
    # values, and a spin loop would run to max_spin on them (seen on NVIDIA: ~80x slower frames)
    submit = src[src.index("void gua_submit_transparent()") :]
    assert submit.index("if (gl_HelperInvocation) return;") < submit.index("gua_insert(")


@pytest.mark.parametrize("method", METHODS)
def test_tiny_budget_reports_overflow(renderer_factory, method):
    scene = layered_quads_scene(n_layers=16, order="shuffled", seed=2)
    r = renderer_factory("exact", method=method, method_overrides={"budget_mb": 0.01})
    frame = r.render(scene, 64, 64)
    fr = frame.stats["fragments"]
    assert fr["overflow"] > 0 and any("overflow" in w for w in frame.stats["warnings"])
    assert np.isfinite(frame.linear).all() and frame.linear.min() >= 0.0 and frame.linear.max() <= 1.0 + 1e-3


def test_methods_are_registered():
    from guaca_py.methods import method_class, method_ids

    assert set(METHODS) <= set(method_ids())
    assert all(method_class(m).exact and method_class(m).geometry_passes == 1 for m in METHODS)
