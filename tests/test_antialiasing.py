"""antialiasing.samples: coverage-aware A-buffer, per-sample resolve, refusals, supersampled reference;
antialiasing.supersample: the rendered frame box filtered down."""

from __future__ import annotations

import dataclasses
import shutil
import subprocess

import numpy as np
import pytest
from conftest import random_quads

from guaca_py import Renderer
from guaca_py.antialiasing import device_samples, method_refusal, with_samples, with_settings, with_supersample
from guaca_py.errors import ConfigError, LimitError, UnsupportedMethodError
from guaca_py.methods import method_class, method_ids
from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.reference import (
    edge_mask,
    linear_pipeline,
    origin_camera,
    quad_mesh,
    reference_of,
    rmse_255,
    scene_triangles,
    supersampled,
    unlit,
)
from guaca_py.scene.graph import MeshData, Node, Scene, Transform

EXACT = load_pipeline("exact")
ONE_PASS_ABUFFER = ("presort_lf", "presort_lf_et", "presort_lf_merge2_et", "presort_cs_et", "post_sort", "post_merge16")


@pytest.fixture(scope="module")
def aa_renderers(renderer_factory):
    """Exact-pipeline renderers by (samples, method), made once per module."""
    made: dict = {}

    def get(samples: int, method: str = "presort_lf_et") -> Renderer:
        if (samples, method) not in made:
            made[samples, method] = renderer_factory(with_samples(EXACT, samples), method=method)
        return made[samples, method]

    return get


@pytest.mark.parametrize("mode", ["samples 4", "supersample 2"])
def test_antialiasing_at_least_halves_edge_error(aa_renderers, renderer_factory, mode):
    """Acceptance: edge RMSE against the 8x8-supersampled exact frame falls >= 2x from 1 sample to 4 samples or supersample 2."""
    size = 80
    scene = random_quads(0)
    ref = supersampled(aa_renderers(1), scene, size, size, 8)
    tris, _, _ = scene_triangles(scene)
    edges = edge_mask(tris, scene.camera, size, size, 0.5)
    one = rmse_255(aa_renderers(1).render(scene, size, size).linear, ref.image, edges)
    r = aa_renderers(4) if mode == "samples 4" else renderer_factory(with_supersample(EXACT, 2))
    better = rmse_255(r.render(scene, size, size).linear, ref.image, edges)
    assert edges.sum() > 500
    assert one > 5.0  # aliasing is there to remove
    assert one / better >= 2.0, (one, better)


@pytest.mark.parametrize("method", ONE_PASS_ABUFFER)
def test_multisampled_interior_stays_exact(aa_renderers, method):
    """With 4 samples every one-pass A-buffer method still matches the float64 reference off edges."""
    size = 64
    scene = random_quads(1)
    ref, edges, _ = reference_of(scene, size, size)
    frame = aa_renderers(4, method).render(scene, size, size)
    err = np.abs(np.clip(frame.linear, 0, 1) - np.clip(ref, 0, 1)).max(axis=2) * 255
    assert err[~edges].max() <= 2.0, (method, err[~edges].max())
    assert frame.stats["antialiasing"]["samples"] >= 4
    assert err[edges].max() > 2.0  # edges differ from the centre sample: they are anti-aliased


def test_one_sample_is_unchanged(aa_renderers, renderer_factory):
    """samples: 1 is the plain pipeline: same image bits, no coverage stored, no multisampled G-buffer."""
    scene = random_quads(2)
    plain = renderer_factory("exact", method="presort_lf_et").render(scene, 48, 48)
    r = aa_renderers(1)
    one = r.render(scene, 48, 48)
    assert np.array_equal(plain.linear, one.linear)
    words = np.frombuffer(r.method._nodes.read(), np.uint32).reshape(-1, 8)
    used = one.stats["fragments"]["nodes_requested"]
    assert used > 0 and not (words[1 : used + 1, 6] >> 16).any()
    assert one.stats["antialiasing"] == {"samples": 1}
    assert one.stats["memory"]["gbuffer"] == 48 * 48 * 28


def _node_masks(method, pixel: int, with_tie: bool = False) -> list:
    """Coverage masks (or (tie id, mask) pairs) of the nodes in the list of `pixel` (32- or 64-bit links)."""
    links = np.frombuffer(method._links.read(), np.uint64 if method.link_bytes == 8 else np.uint32)
    words = np.frombuffer(method._nodes.read(), np.uint32).reshape(-1, 8)
    n, masks = int(links[pixel]) & 0xFFFFFFFF, []
    while n:
        mask = int(words[n, 6]) >> 16
        masks.append((int(words[n, 7]), mask) if with_tie else mask)
        n = int(links[method._pixels + n]) & 0xFFFFFFFF
    return masks


def _coverage_by_primitive(method, pixels: int) -> list[dict]:
    """Per pixel: tie id (draw, primitive) -> the samples its fragments cover there."""
    out = []
    for p in range(pixels):
        cover: dict = {}
        for tie, mask in _node_masks(method, p, with_tie=True):
            cover[tie] = cover.get(tie, 0) | mask
        out.append(cover)
    return out


def half_screen_scene(alpha: float = 0.5, behind: bool = False) -> Scene:
    """A quad whose right edge is the screen's vertical centre line (x = 0), optionally a full-screen one behind."""
    nodes = [Node("left", Transform((-2.0, 0.0, 0.0)), quad_mesh(2.0, 3.0), unlit((1.0, 0.2, 0.1), alpha))]
    if behind:
        nodes.append(Node("behind", Transform((0.7, 0.6, -1.0)), quad_mesh(4.0, 4.0), unlit((0.1, 0.9, 0.2), 0.5)))
    return Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), nodes=nodes)


def test_half_covered_pixel_stores_half_the_samples(aa_renderers):
    """At 63 px the centre line halves pixel column 31: its node covers 2 of 4 samples, the colour is the mean."""
    r = aa_renderers(4)
    if r.samples != 4:
        pytest.skip(f"the device renders {r.samples} samples for 4")
    size, row = 63, 31
    frame = r.render(half_screen_scene(), size, size)
    masks = _node_masks(r.method, row * size + 31)
    assert len(masks) == 1 and bin(masks[0]).count("1") == 2, masks
    assert _node_masks(r.method, row * size + 20) == [0xF]
    assert _node_masks(r.method, row * size + 40) == []
    bg, c = np.array([0.05, 0.08, 0.12]), np.array([1.0, 0.2, 0.1])
    covered = 0.5 * c + 0.5 * bg
    got = frame.linear[size - 1 - row, 31]
    assert np.abs(got - 0.5 * (covered + bg)).max() * 255 < 1.0, got
    assert frame.stats["memory"]["abuffer_node_bytes"] == r.method.node_bytes == 32 + r.method.link_bytes
    assert frame.stats["memory"]["gbuffer"] == size * size * 28 * 4


def test_early_termination_keeps_fragments_of_unsaturated_samples(aa_renderers):
    """A saturating quad over half a pixel must not hide the fragment behind it at the other half."""
    r = aa_renderers(4)
    if r.samples != 4:
        pytest.skip(f"the device renders {r.samples} samples for 4")
    size, row = 63, 31
    frame = r.render(half_screen_scene(alpha=0.9995, behind=True), size, size)
    # behind fully covered pixels: refused, or culled by the saturation depth the front quad set
    assert frame.stats["fragments"]["early_termination_culled"] > 0
    bg, a, b = np.array([0.05, 0.08, 0.12]), np.array([1.0, 0.2, 0.1]), np.array([0.1, 0.9, 0.2])
    left = 0.9995 * a + 0.0005 * bg  # saturated at 0.9995 >= 0.999: the walk stops for these samples
    right = 0.5 * b + 0.5 * bg
    got = frame.linear[size - 1 - row, 31]
    assert np.abs(got - 0.5 * (left + right)).max() * 255 < 1.0, got
    masks = _node_masks(r.method, row * size + 31)
    assert len(masks) == 2 and bin(masks[0]).count("1") == 2 and masks[1] == 0xF, masks


def test_early_termination_drops_a_partial_fragment_hidden_at_its_own_samples(aa_renderers):
    """Per-sample early termination: behind a saturating edge, a fragment covering the same samples is refused."""
    r = aa_renderers(4)
    if r.samples != 4:
        pytest.skip(f"the device renders {r.samples} samples for 4")
    size, row = 63, 31
    scene = half_screen_scene(alpha=0.9995)
    # the same half-screen quad farther away: its right edge projects onto the same centre line
    scene.nodes.append(Node("behind", Transform((-2.0, 0.0, -1.0)), quad_mesh(2.0, 3.0), unlit((0.1, 0.9, 0.2), 0.5)))
    frame = r.render(scene, size, size)
    edge = _node_masks(r.method, row * size + 31)
    assert len(edge) == 1 and bin(edge[0]).count("1") == 2, edge  # the fragment behind was not stored
    # ... nor behind any covered pixel of the edge (refused, or culled by the saturation depth)
    assert frame.stats["fragments"]["early_termination_culled"] >= size
    bg, a = np.array([0.05, 0.08, 0.12]), np.array([1.0, 0.2, 0.1])
    got = frame.linear[size - 1 - row, 31]
    assert np.abs(got - 0.5 * ((0.9995 * a + 0.0005 * bg) + bg)).max() * 255 < 1.0, got


@pytest.mark.parametrize("method", [m for m in method_ids() if not method_class(m).supports_antialiasing])
def test_methods_without_coverage_refuse(gl_context, method):
    """Peeling, counted storage and approximate blends refuse samples > 1, naming the method and the way out."""
    reason = method_refusal(method_class(method), 4)
    assert reason and f"'{method}'" in reason and "presort_lf_et" in reason
    with pytest.raises(UnsupportedMethodError, match=method):
        Renderer(with_samples(EXACT, 2), ctx=gl_context, method=method)


def test_compute_raster_makes_the_hardware_coverage(renderer_factory):
    """raster: compute tests coverage at the device's sample points: same masks, same image as the hardware."""
    hw = renderer_factory(with_samples(EXACT, 4), method="presort_lf_et", method_overrides={"raster": "hardware"})
    cs = renderer_factory(with_samples(EXACT, 4), method="presort_lf_et", method_overrides={"raster": "compute"})
    if hw.samples != 4:
        pytest.skip(f"the device renders {hw.samples} samples for 4")
    size, row = 63, 31
    a, b = hw.render(half_screen_scene(), size, size), cs.render(half_screen_scene(), size, size)
    assert set(b.stats["raster"]["why"]) == {"compute: raster: compute"}, b.stats["raster"]
    for col in (20, 31, 40):  # inside, on the edge (2 of 4 samples), outside
        assert _node_masks(cs.method, row * size + col) == _node_masks(hw.method, row * size + col)
    assert np.abs(a.linear - b.linear).max() * 255 < 1.0
    scene = random_quads(0)
    a, b = hw.render(scene, 64, 64), cs.render(scene, 64, 64)
    assert b.stats["fragments"]["stored"] <= a.stats["fragments"]["stored"]
    err = np.abs(a.linear - b.linear).max(axis=2) * 255
    # where quads intersect inside a pixel the order is per fragment, decided at the centroid of
    # its samples: the two may order a few such pixels differently, and be equally right
    assert np.mean(err <= 1.0) > 0.98, np.mean(err <= 1.0)
    ref = supersampled(hw, scene, 64, 64, 8)
    tris, _, _ = scene_triangles(scene)
    edges = edge_mask(tris, scene.camera, 64, 64, 0.5)
    hw_err, cs_err = rmse_255(a.linear, ref.image, edges), rmse_255(b.linear, ref.image, edges)
    assert cs_err <= 1.1 * hw_err, (cs_err, hw_err)
    # Mesa llvmpipe may shade one primitive twice in a pixel (two nodes, disjoint masks); the
    # compute rasterizer makes one fragment per primitive and pixel: the samples each covers agree.
    # (Without the opaque quad: the compute masks leave out samples behind it, gl_SampleMaskIn
    # need not; the composite tests each sample's depth either way.)
    clear = dataclasses.replace(scene, nodes=[n for n in scene.nodes if n.name != "opaque"])
    hw.render(clear, 64, 64), cs.render(clear, 64, 64)
    same = [
        x == y for x, y in zip(_coverage_by_primitive(hw.method, 64 * 64), _coverage_by_primitive(cs.method, 64 * 64))
    ]
    # a sample within rounding of an edge may fall on the other side (llvmpipe: 2 pixels of 4096)
    assert np.mean(same) >= 0.995, (np.mean(same), len(same) - sum(same))


def test_compute_raster_clips_each_sample_at_near_and_far(renderer_factory):
    """Quads through the far and the near plane, every corner in front of the eye (the fixed-point
    path, which then tests each sample's depth): the compute masks and image are the hardware's."""
    hw = renderer_factory(with_samples(EXACT, 4), method="presort_lf_et", method_overrides={"raster": "hardware"})
    cs = renderer_factory(with_samples(EXACT, 4), method="presort_lf_et", method_overrides={"raster": "compute"})
    if hw.samples != 4:
        pytest.skip(f"the device renders {hw.samples} samples for 4")

    def quad(name, corners, color) -> Node:
        # two triangles over four explicit corners, all in front of the eye (z < 5): fixed point
        pos = np.array(corners, dtype=np.float32)
        n = np.cross(pos[1] - pos[0], pos[2] - pos[0])
        normals = np.tile(n / np.linalg.norm(n), (4, 1)).astype(np.float32)
        idx = np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)
        return Node(name, Transform(), MeshData(pos, normals, np.zeros((4, 2), np.float32), idx), unlit(color, 0.5))

    def scene(near: float, far: float) -> Scene:
        # view distances (eye at z = 5): the far quad 6-17, its depth changing along a diagonal of
        # the screen; the near quad 0.4-3
        nodes = [
            quad("far", [(-2, -1.5, -1), (2, -1.5, -6), (2, 1.5, -12), (-2, 1.5, -7)], (0.9, 0.3, 0.1)),
            quad("near", [(-0.4, -0.4, 4.6), (0.4, -0.4, 4.2), (0.4, 0.4, 2.0), (-0.4, 0.4, 3.0)], (0.1, 0.8, 0.3)),
        ]
        camera = dataclasses.replace(origin_camera(), near=near, far=far)
        return Scene(camera=camera, background=(0.05, 0.08, 0.12), nodes=nodes)

    clipped, whole = scene(1.0, 9.0), scene(0.01, 100.0)
    a, b = hw.render(clipped, 64, 64), cs.render(clipped, 64, 64)
    masks_cs = _coverage_by_primitive(cs.method, 64 * 64)
    masks_hw = _coverage_by_primitive(hw.method, 64 * 64)
    stored = b.stats["fragments"]["stored"]
    # both planes cut fragments: at 4 samples only the per-sample depth test clips in fixed point
    assert stored < 0.9 * cs.render(whole, 64, 64).stats["fragments"]["stored"]
    err = np.abs(a.linear - b.linear).max(axis=2) * 255
    assert np.mean(err <= 1.0) > 0.98, np.mean(err <= 1.0)
    same = [x == y for x, y in zip(masks_hw, masks_cs)]
    assert np.mean(same) >= 0.99, (np.mean(same), len(same) - sum(same))


def test_sample_counts_validated(gl_context):
    """Only 1/2/4/8, in a mapping; counts above the device's are refused with its limit."""
    with pytest.raises(ConfigError, match="antialiasing.samples"):
        pipeline_from_text("antialiasing: {samples: 3}\npasses: [geometry, light_culling, composite]")
    with pytest.raises(ConfigError, match="antialiasing"):
        pipeline_from_text("antialiasing: 4\npasses: [geometry, light_culling, composite]")
    cfg = pipeline_from_text("antialiasing: {samples: 2}\npasses: [geometry, light_culling, composite]")
    assert cfg.antialiasing == {"samples": 2, "supersample": 1, "auto": False}
    most = device_samples(gl_context)
    if most >= 8:
        pytest.skip("the device renders 8 samples")
    with pytest.raises(UnsupportedMethodError, match=f"at most {most}"):
        Renderer(with_samples(EXACT, 8), ctx=gl_context)


def test_tiled_reference_matches_one_tile(aa_renderers):
    """The supersampled reference is the same whether rendered in one target or in tiles."""
    scene = random_quads(3, n=6)
    whole = supersampled(aa_renderers(1), scene, 40, 40, 4)
    tiled = supersampled(aa_renderers(1), scene, 40, 40, 4, tile_px=64)
    assert whole.tiles == 1 and tiled.tiles == 9
    diff = np.abs(whole.image - tiled.image).max(axis=2)
    assert np.mean(diff < 1e-3) > 0.995 and diff.mean() < 1e-3


def test_opaque_only_scene_is_antialiased(aa_renderers):
    """Without transparent draws the multisampled G-buffer alone is resolved: exact inside, blended at edges."""
    size = 48
    nodes = [Node("tri", Transform((0.0, 0.0, 0.0), (0.0, 0.0, 17.0)), quad_mesh(1.2, 0.8), unlit((0.9, 0.6, 0.2)))]
    scene = Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), nodes=nodes)
    ref, edges, _ = reference_of(scene, size, size)
    frame = aa_renderers(4).render(scene, size, size)
    assert frame.stats["fragments"] == {"stored": 0}
    err = np.abs(np.clip(frame.linear, 0, 1) - ref).max(axis=2) * 255
    assert err[~edges].max() <= 1.0
    mixed = frame.linear[edges]  # edge pixels take values between the quad and the background
    assert np.mean(np.abs(mixed - ref[edges]).max(axis=1) > 0.05) > 0.3


def test_lit_default_pipeline_with_samples(renderer_factory):
    """The lit demo through the default pipeline (PBR, light grid, tone mapping, FXAA) at 4 samples."""
    from guaca_py.scene.loader import demo_scene

    scene = demo_scene()
    one = renderer_factory("default").render(scene, 64, 64)
    four = renderer_factory(with_samples(load_pipeline("default"), 4)).render(scene, 64, 64)
    assert four.stats["antialiasing"]["samples"] >= 4 and not four.stats.get("warnings")
    diff = np.abs(one.image.astype(int) - four.image.astype(int)).max(axis=2)
    assert np.median(diff) <= 2 and diff.max() > 10  # the same picture, different edges


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslangValidator (glslang-tools) not installed")
@pytest.mark.parametrize("method", ["presort_lf_et", "presort_lf_merge2_et", "presort_cs_et", "post_merge16"])
def test_gpu_variants_at_8_samples_pass_the_reference_compiler(aa_renderers, tmp_path, monkeypatch, method):
    """The NVIDIA variants (64-bit insertion, ballots, interlock) at 8 samples, which this device cannot build
    (the composite also supersampled 3x); the 64-bit list walk passes nearer records with plain loads."""
    from guaca_py.passes import composite
    from guaca_py.pipeline.drawlist import build_draw_list
    from guaca_py.renderer import method_settings

    r = aa_renderers(4, method)
    seen = {}
    original = composite.CompositePass.compile

    def spy(self, variables, template=None):
        seen.update(variables)
        return original(self, variables, template)

    monkeypatch.setattr(composite.CompositePass, "compile", spy)
    scene = random_quads(4, n=3)
    r.render(scene, 16, 16)
    caps = dataclasses.replace(r.caps, atomic_int64=True, shader_ballot=True, fragment_interlock=True)
    m = method_class(method)(method_settings(method, {}), caps)
    m.aa_samples = 8
    sources = {}
    monkeypatch.setattr(r.shaders, "program", lambda stages, smap=None, label="": stages)
    monkeypatch.setattr(r.device, "antialiasing", dataclasses.replace(r.device.antialiasing, samples=8))
    draw = next(d for d in build_draw_list(scene, r.materials) if d.transparent)
    for stage, (template, variables) in r.raster.hardware.program(m, draw, True).items():
        sources["frag" if stage == "fragment_shader" else "vert"] = r.shaders.render(template, **variables)
    cvars = dict(seen, method_extensions=m.resolve_extensions(), **m.template_vars())
    cvars.update(aa_samples=8, output_format="rgba32f")
    sources["comp"] = r.shaders.render("composite/shade_composite.comp.j2", **cvars)
    cvars.update(supersample=3, local_edge=9)
    supersampled = r.shaders.render("composite/shade_composite.comp.j2", **cvars)
    assert "gl_SampleMaskIn" in sources["frag"] and "sampler2DMS" in sources["comp"]
    # an invocation per rendered pixel, 9 x 9 workgroups of whole 3 x 3 blocks
    assert "const int GUA_SS = 3;" in supersampled and "local_size_x = 9" in supersampled
    assert "uint64_t" in sources["frag"] or m.link_bytes == 4
    if method.startswith("presort_lf"):  # the sorted 64-bit walk: loads past nearer records
        assert "uint64_t seen = gua_links[slot];" in sources["frag"]
    for stage, text in [*sources.items(), ("comp", supersampled)]:
        path = tmp_path / f"s.{stage}"
        path.write_text(text)
        run = subprocess.run(["glslangValidator", "-S", stage, str(path)], capture_output=True, text=True)
        assert run.returncode == 0, (stage, run.stdout[-2000:])


# ----------------------------------------------------------------------------- supersample
def box_filter(image: np.ndarray, k: int) -> np.ndarray:
    """Mean of each k x k block of an (H, W, C) image."""
    h, w, c = image.shape
    return image.reshape(h // k, k, w // k, k, c).mean(axis=(1, 3))


# (base pipeline, samples, method (None: the pipeline's), random_quads seed and quads, output size)
SUPERSAMPLE_CASES = [
    pytest.param(linear_pipeline(), 1, None, 4, 10, 48, id="linear"),
    pytest.param(EXACT, 4, None, 5, 10, 32, id="with-samples-4"),
    *(pytest.param(linear_pipeline(), 1, m, 6, 5, 16, id=f"method-{m}") for m in method_ids()),
]


@pytest.mark.parametrize(("base", "samples", "method", "seed", "n", "size"), SUPERSAMPLE_CASES)
def test_supersample_is_the_box_filter_of_the_larger_frame(renderer_factory, base, samples, method, seed, n, size):
    """supersample 2 equals the 2x frame averaged in 2x2 blocks (float tolerance) for the linear pipeline, at 4
    samples and for every method (A-buffers, peeling, counted, approximate); an exact method's 2x frame is the
    float64 reference's off the edges."""
    scene = random_quads(seed, n)
    big = renderer_factory(with_samples(base, samples), method=method).render(scene, 2 * size, 2 * size)
    r = renderer_factory(with_settings(base, {"samples": samples, "supersample": 2}, "test"), method=method)
    frame = r.render(scene, size, size)
    assert frame.linear.shape == (size, size, 3) and frame.image.shape == (size, size, 3)
    np.testing.assert_allclose(frame.linear, box_filter(big.linear, 2), atol=1e-6)
    if r.method.exact:
        ref, edges, _ = reference_of(scene, 2 * size, 2 * size)
        assert (np.abs(np.clip(big.linear, 0, 1) - ref).max(axis=2)[~edges] * 255).max() <= 2.0
    aa = frame.stats["antialiasing"]
    assert aa == {**big.stats["antialiasing"], "supersample": 2}  # the rendered frame's samples
    assert aa["samples"] == samples if samples == 1 else aa["samples"] >= samples  # a device may round 2-8 up
    assert frame.stats["resolution"] == [size, size] and frame.stats["render_resolution"] == [2 * size, 2 * size]
    assert frame.stats["memory"]["gbuffer"] == (2 * size) ** 2 * 28 * aa["samples"]  # the rendered frame's
    assert big.stats["render_resolution"] == big.stats["resolution"] == [2 * size, 2 * size]


def test_supersample_validated_and_held_to_the_device(gl_context, renderer_factory):
    """Only 1/2/3/4; the rendered size must fit the device, and the error names antialiasing.supersample."""
    with pytest.raises(ConfigError, match=r"antialiasing.*supersample.*must be one of 1, 2, 3, 4, got 5") as err:
        pipeline_from_text("antialiasing: {supersample: 5}\npasses: [geometry, light_culling, composite]", "p.yaml")
    assert err.value.line == 1
    r = renderer_factory(with_supersample(EXACT, 4))
    wide = r.caps.limits.max_framebuffer[0] // 4 + 1  # fits alone, not four times over
    with pytest.raises(LimitError) as err:
        r.render(random_quads(0, n=1), wide, 8)
    assert err.value.key == "antialiasing.supersample"
    assert f"renders {4 * wide}x32" in str(err.value) and "use antialiasing.supersample 3" in str(err.value)


def test_reference_tile_that_overflows_is_rendered_again_as_four(renderer_factory):
    """A tile whose pool overflows is split (that tile alone) until the fragments fit: the reference is then
    exact and equals the one rendered in small tiles from the start."""
    scene = random_quads(3, n=6)
    small_pool = renderer_factory(EXACT, method="presort_lf", method_overrides={"budget_mb": 0.15})
    direct = supersampled(small_pool, scene, 40, 40, 4, tile_px=160, min_tile_px=160)
    assert direct.overflow > 0 and direct.tiles == 1  # one 160² tile does not fit the pool
    # 20² rendered pixels under 6 quads make at most 2,400 nodes, well inside the 0.15 MB pool (~3,900 nodes
    # of 40 B) whatever the device's insertion path leaves unlinked; larger tiles may or may not fit
    split = supersampled(small_pool, scene, 40, 40, 4, tile_px=160, min_tile_px=20)
    assert split.overflow == 0 and split.tiles > 1
    small = supersampled(small_pool, scene, 40, 40, 4, tile_px=20)
    assert small.overflow == 0
    diff = np.abs(split.image - small.image).max(axis=2)
    assert np.mean(diff < 1e-3) > 0.995 and diff.mean() < 1e-3
