"""The peeling family against the float64 reference: depth, dual, multi-layer, hybrid and coherent
layer peeling; pass counts on sorted input, the pass cap, the 8-bit stencil overflow, the node pool."""

from __future__ import annotations

import colorsys
import dataclasses
import shutil
import subprocess

import numpy as np
import pytest
from conftest import lit_demo_difference, quad_node, simple_scene
from exact_frames import ReferenceCache, render_interpenetrating_exactly, render_layered_exactly

from guaca_py.reference import compare, layered_quads_scene

SIZE = 64
METHODS = [
    "depth_peeling",
    "dual_depth_peeling",
    "multilayer_depth_peeling",
    "hybrid_layer_peeling",
    "coherent_layer_peeling",
]
_REFS = ReferenceCache()


def reference_of(key, scene, w=SIZE, h=SIZE):
    """Reference image, edge exclusion mask and layer counts (cached: several methods share a scene)."""
    return _REFS.of(key, scene, w, h)


def planes(n, alpha, order, size=12.0, z0=2.0, z1=-3.0):
    """n screen-covering planes from z0 (front) to z1, distinct colours, in the given submission order."""
    nodes = [
        quad_node(f"p{i:03d}", z0 + (z1 - z0) * i / (n - 1), colorsys.hsv_to_rgb(i / n, 0.8, 0.95), alpha, size=size)
        for i in range(n)
    ]
    if order == "back_to_front":
        nodes = nodes[::-1]
    elif order == "shuffled":
        nodes = [nodes[i] for i in np.random.default_rng(7).permutation(n)]
    return simple_scene(nodes, background=(0.05, 0.08, 0.12))


def check_stats(frame, method):
    """What every peeling method reports: passes, fragments, memory (used <= allocated), no warnings."""
    s = frame.stats
    assert s["method"] == method and s["geometry_passes"] >= 1
    fr = s["fragments"]
    assert fr["truncated"] == 0 and fr["stored"] == fr["peeled"] + fr["composited"] > 0, fr
    mem = s["memory"]
    assert mem["peel_acc_front"] == SIZE * SIZE * 16 and mem["peel_bounds"] == SIZE * SIZE * 16
    for k, v in mem.items():
        if k.endswith("_used"):
            assert 0 < v <= mem[k[:-5]], (k, mem)
    assert not s.get("warnings"), s.get("warnings")
    return fr


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("order", ["front_to_back", "back_to_front", "shuffled"])
def test_exact_layered_with_opaque(renderers, method, order):
    check_stats(render_layered_exactly(_REFS, renderers(method), order, SIZE), method)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("order", ["forward", "reverse", "shuffled"])
def test_exact_interpenetrating(renderers, method, order):
    check_stats(render_interpenetrating_exactly(_REFS, renderers(method), order, SIZE), method)


@pytest.mark.parametrize("method", METHODS)
def test_exact_deep_shuffled_planes(renderers, method):
    # 24 planes over every pixel, shuffled: every pixel needs all 24 layers in order
    scene = planes(24, 0.22, "shuffled")
    ref, mask, layers = reference_of(("planes24",), scene)
    assert layers.min() == 24
    frame = renderers(method).render(scene, SIZE, SIZE)
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0
    check_stats(frame, method)


@pytest.mark.parametrize("method", METHODS)
def test_coplanar_ties_resolve_in_submission_order(renderers, method):
    # three identical coplanar planes at one depth among others: equal keys break ties by
    # (draw, primitive), like the reference's stable sort, so none is lost or doubled
    nodes = [quad_node("back", -1.0, (0.2, 0.3, 0.9), 0.5, size=12.0)]
    nodes += [
        quad_node(f"tie{i}", 0.0, c, 0.4, size=12.0)
        for i, c in enumerate([(0.9, 0.1, 0.1), (0.1, 0.9, 0.1), (0.9, 0.9, 0.1)])
    ]
    nodes.append(quad_node("front", 1.0, (0.9, 0.5, 0.9), 0.3, size=12.0))
    scene = simple_scene([nodes[i] for i in (3, 0, 1, 4, 2)], background=(0.05, 0.08, 0.12))
    ref, mask, layers = reference_of(("ties",), scene)
    frame = renderers(method).render(scene, SIZE, SIZE)
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0
    assert frame.stats["fragments"]["stored"] == 5 * SIZE * SIZE


def test_sorted_input_needs_fewer_passes(renderers):
    # pre-sorted (front-to-back) layered quads: hybrid and coherent composite whole in-order runs
    scene = layered_quads_scene(n_layers=18, order="front_to_back", seed=3)
    passes = {m: renderers(m).render(scene, SIZE, SIZE).stats["geometry_passes"] for m in METHODS}
    depth = passes["depth_peeling"]
    assert depth >= 12, passes
    assert passes["coherent_layer_peeling"] == 5 < depth, passes  # one iteration of five passes
    assert passes["hybrid_layer_peeling"] == 1 < depth, passes  # every draw is in the sorted chain
    assert max(passes["dual_depth_peeling"], passes["multilayer_depth_peeling"]) < depth, passes


@pytest.mark.parametrize(
    "method, expected",
    [
        ("depth_peeling", 16),
        ("dual_depth_peeling", 8),
        ("multilayer_depth_peeling", 4),
        ("coherent_layer_peeling", 5),
        ("hybrid_layer_peeling", 1),
    ],
)
def test_pass_counts_on_sorted_planes(renderers, method, expected):
    # 16 planes over every pixel, front to back, nothing saturates: one layer per pass, two (both
    # ends), four (M = 4), one coherent iteration, one composite of the sorted chain. A pass that
    # sees nothing left behind the layers it peeled is the last one (no empty pass at the end).
    frame = renderers(method).render(planes(16, 0.2, "front_to_back"), SIZE, SIZE)
    assert frame.stats["geometry_passes"] == expected
    assert frame.stats["fragments"]["stored"] == 16 * SIZE * SIZE


def test_reverse_order_costs_coherent_more_than_sorted(renderers):
    # the same stack submitted back to front defeats the in-order runs (the paper's worst case)
    fast = renderers("coherent_layer_peeling").render(planes(16, 0.2, "front_to_back"), SIZE, SIZE)
    slow = renderers("coherent_layer_peeling").render(planes(16, 0.2, "back_to_front"), SIZE, SIZE)
    assert fast.stats["geometry_passes"] == 5
    assert slow.stats["geometry_passes"] > 5 * 4


@pytest.mark.parametrize(
    "method, per_pass, cap",
    [("depth_peeling", 1, 3)] + [("dual_depth_peeling", 2, cap) for cap in (1, 2, 5, 6)],
)
def test_pass_cap_counts_what_is_left(renderers, method, per_pass, cap):
    # depth peeling peels a layer a pass, dual depth peeling two (its first pass also counts the
    # pixel's fragments); the step after the last pass the cap allows adds up what is left (dual at
    # 6: none, 12 / 2)
    scene = planes(12, 0.15, "shuffled")
    peeled = min(per_pass * cap, 12)
    frame = renderers(method, max_passes=cap).render(scene, SIZE, SIZE)
    s = frame.stats
    assert s["geometry_passes"] == cap
    assert s["fragments"]["peeled"] == peeled * SIZE * SIZE
    assert s["fragments"]["truncated"] == (12 - peeled) * SIZE * SIZE
    assert any(f"max_passes={cap}" in w for w in s.get("warnings", [])) == (peeled < 12), s.get("warnings")
    if peeled < 12:
        ref, mask, _ = reference_of(("planes12",), scene)
        assert compare(frame.image, ref, mask)["max_abs_255"] > 10  # the missing layers show


@pytest.mark.parametrize(
    "method, cap",
    [
        ("multilayer_depth_peeling", 1),
        ("coherent_layer_peeling", 7),
        ("hybrid_layer_peeling", 4),
    ],
)
def test_other_caps_report_truncation(renderers, method, cap):
    frame = renderers(method, max_passes=cap).render(planes(12, 0.15, "back_to_front"), SIZE, SIZE)
    assert frame.stats["geometry_passes"] <= cap
    assert frame.stats["fragments"]["truncated"] > 0
    assert any(f"max_passes={cap}" in w for w in frame.stats["warnings"])


def test_coherent_stencil_overflow_is_detected_and_handled(renderers):
    # 260 planes submitted back to front: pass 1 sees every one of them update the z-buffer, which
    # an 8-bit stencil cannot count; the method falls back to one layer per iteration there
    scene = planes(260, 0.3, "back_to_front", size=40.0, z0=2.0, z1=-8.0)
    ref, mask, layers = reference_of(("overflow",), scene, 8, 8)
    assert layers.min() == 260
    frame = renderers("coherent_layer_peeling").render(scene, 8, 8)
    s = frame.stats
    # each iteration then peels one layer; pass 1 of iteration k counts 261 - k updates, which
    # the 8-bit stencil holds from k = 6 on (255): 5 iterations x 64 pixels overflow
    assert s["fragments"]["stencil_overflow_pixels"] == 5 * 64
    assert any("stencil overflow" in w for w in s["warnings"])
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_multilayer_small_pool_stays_exact(renderers):
    # a fixed pool far below one node per fragment: overflowing passes only shade what is safe
    scene = planes(10, 0.25, "back_to_front")
    ref, mask, _ = reference_of(("planes10",), scene)
    frame = renderers("multilayer_depth_peeling", pool_mb=0.125).render(scene, SIZE, SIZE)
    s = frame.stats
    assert s["fragments"]["pool_overflow"] > 0 and s["fragments"]["truncated"] == 0
    assert any("pool overflowed" in w for w in s["warnings"])
    assert s["memory"]["peel_ml_pool"] == 4096 * 32
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_multilayer_auto_pool_grows(renderers):
    # back to front, every fragment is nearer than the ones before it and takes a node: the first
    # pool (one node per pixel and layer) overflows, grows to the pass's need, and stays exact
    scene = planes(10, 0.25, "back_to_front")
    ref, mask, _ = reference_of(("planes10",), scene)
    frame = renderers("multilayer_depth_peeling", layers_per_pass=2).render(scene, SIZE, SIZE)
    fr, mem = frame.stats["fragments"], frame.stats["memory"]
    assert fr["pool_grown"] >= 1 and fr["truncated"] == 0
    assert mem["peel_ml_pool"] >= 10 * SIZE * SIZE * 32 and mem["peel_ml_pool_used"] <= mem["peel_ml_pool"]
    assert frame.stats["geometry_passes"] <= 6
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_multilayer_auto_pool_shrinks_to_the_need(renderer_factory):
    # the first pool is one node per pixel and layer; a small shallow scene uses a fraction of it, so the
    # next frame holds about what was used, and a deeper scene after that grows it again
    r = renderer_factory("exact", method="multilayer_depth_peeling")
    shallow, deep = planes(3, 0.3, "shuffled", size=1.5), planes(10, 0.25, "back_to_front")
    first = r.render(shallow, SIZE, SIZE).stats["memory"]
    second = r.render(shallow, SIZE, SIZE).stats["memory"]
    assert second["peel_ml_pool"] < first["peel_ml_pool"] // 2
    assert second["peel_ml_pool_used"] <= second["peel_ml_pool"] <= 1.2 * first["peel_ml_pool_used"] + 4096 * 32
    ref, mask, _ = reference_of(("planes10",), deep)
    frame = r.render(deep, SIZE, SIZE)
    assert frame.stats["fragments"]["pool_grown"] >= 1 and frame.stats["fragments"]["truncated"] == 0
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_hybrid_split_keeps_longest_sorted_chain():
    from guaca_py.methods.peeling_coherent import sorted_chain

    ivs = [(1.0, 1.5), (4.0, 4.5), (2.0, 2.5), None, (3.0, 3.2), (2.4, 3.0), (5.0, 6.0)]
    assert sorted_chain(ivs) == [0, 2, 4, 6]
    assert sorted_chain([None, None]) == []
    assert sorted_chain([(3.0, 4.0), (1.0, 2.0)]) in ([0], [1])


def test_unsupported_without_ordering(renderer_factory, gl_context):
    from guaca_py.context import detect_capabilities
    from guaca_py.errors import UnsupportedMethodError

    with pytest.raises(UnsupportedMethodError, match="framebuffer_fetch"):
        renderer_factory("exact", method="depth_peeling", disable=("framebuffer_fetch", "fragment_interlock"))
    # asking for the ordering extension the device lacks (the other one present) is refused too
    caps = detect_capabilities(gl_context)
    missing = "interlock" if caps.framebuffer_fetch else "fetch"
    off = "fragment_interlock" if missing == "interlock" else "framebuffer_fetch"
    with pytest.raises(UnsupportedMethodError, match=f"ordering '{missing}'"):
        renderer_factory(
            "exact", method="coherent_layer_peeling", disable=(off,), method_overrides={"ordering": missing}
        )
    # multi-layer peeling only needs 32-bit atomics
    r = renderer_factory(
        "exact", method="multilayer_depth_peeling", disable=("framebuffer_fetch", "fragment_interlock")
    )
    assert r.method.order is None


@pytest.mark.parametrize("method", METHODS)
def test_lit_demo_shades_like_presort_lf(renderer_factory, lit_demo_presort, method):
    # lit, tone-mapped demo with the light grid: peeled layers (shaded by the steps from stored
    # payloads) and in-place composited runs shade exactly like the A-buffer's composite
    # display-encoded (tone curve + sRGB + FXAA) images: NVIDIA's compute-shader shading of peeled
    # layers rounds differently from the composite's fragment shader by up to 2/255 there
    assert lit_demo_difference(renderer_factory, lit_demo_presort, method) <= 2


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslangValidator (glslang-tools) not installed")
@pytest.mark.parametrize("method", ["depth_peeling", "dual_depth_peeling"])
def test_interlock_variant_passes_the_reference_compiler(renderer_factory, tmp_path, monkeypatch, method):
    """The NVIDIA path (ordered slots as images inside the fragment shader interlock), which this device cannot build."""
    from guaca_py.methods import method_class
    from guaca_py.pipeline.drawlist import build_draw_list
    from guaca_py.renderer import method_settings

    r = renderer_factory("exact", method=method)
    scene = layered_quads_scene(n_layers=2, order="shuffled", seed=1)
    r.render(scene, 8, 8)  # the light lookup's template variables, which the shading phases need
    caps = dataclasses.replace(r.caps, fragment_interlock=True, framebuffer_fetch=False)
    m = method_class(method)(method_settings(method, {}), caps)
    assert m.order == "interlock"
    m._shading = r.method._shading
    monkeypatch.setattr(r.shaders, "program", lambda stages, smap=None, label="": stages)
    draw = next(d for d in build_draw_list(scene, r.materials) if d.transparent)
    # their ordered geometry phases (dual: the first pass, the shading passes)
    phases = ["dual_first", "dual"] if method == "dual_depth_peeling" else ["nearest"]
    for phase in phases:
        m._phase = phase
        for stage, (template, variables) in r.raster.hardware.program(m, draw, True).items():
            text = r.shaders.render(template, **variables)
            if stage == "fragment_shader":
                assert "pixel_interlock_ordered" in text and "imageStore(gua_ord0" in text
            path = tmp_path / ("s.frag" if stage == "fragment_shader" else "s.vert")
            path.write_text(text)
            run = subprocess.run(["glslangValidator", str(path)], capture_output=True, text=True)
            assert run.returncode == 0, (phase, stage, run.stdout[-2000:])
