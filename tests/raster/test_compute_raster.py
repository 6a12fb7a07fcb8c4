"""`transparency.raster: compute`: the compute rasterizer against the float64 reference and the
hardware rasterizer, its coverage rules (shared edges, near plane, facing), materials that need
derivatives, methods that refuse it, its overflow handling and the `auto` rule."""

from __future__ import annotations

import colorsys
import dataclasses
import re
import shutil
import types

import numpy as np
import pytest
from conftest import quad_node, simple_scene
from exact_frames import ReferenceCache

from guaca_py.antialiasing import with_samples
from guaca_py.errors import ConfigError, UnsupportedMethodError
from guaca_py.pipeline.config import load_pipeline
from guaca_py.raster import choice, compute_raster
from guaca_py.reference import compare, edge_mask, interpenetrating_scene, layered_quads_scene, triangle_mesh, unlit
from guaca_py.scene.graph import Light, MaterialInstance, MeshData, Node, Transform

SIZE = 96
ONE_PASS = [
    "presort_lf",
    "presort_lf_et",
    "presort_lf_merge2_et",
    "presort_cs",
    "presort_cs_et",
    "post_sort",
    "post_merge16",
]
_REFS = ReferenceCache()


def both(renderer_factory, method, pipeline="exact", **overrides):
    """(compute, hardware) renderers of one method."""
    return tuple(
        renderer_factory(pipeline, method=method, method_overrides={**overrides, "raster": raster})
        for raster in ("compute", "hardware")
    )


def differing(a, b) -> np.ndarray:
    """(H, W) bool: pixels whose 8-bit colour differs."""
    return (a.astype(int) != b.astype(int)).any(axis=2)


def tessellated_plane(n: int, size: float, jitter: float, seed: int = 0) -> MeshData:
    """A size x size square in the XY plane as 2n² triangles with jittered interior vertices."""
    g = np.linspace(-size / 2, size / 2, n + 1)
    x, y = np.meshgrid(g, g, indexing="xy")
    rng = np.random.default_rng(seed)
    inner = np.zeros_like(x, dtype=bool)
    inner[1:-1, 1:-1] = True
    x = x + np.where(inner, rng.uniform(-jitter, jitter, x.shape), 0.0) * (size / n)
    y = y + np.where(inner, rng.uniform(-jitter, jitter, y.shape), 0.0) * (size / n)
    pos = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1).astype(np.float32)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    quads = np.stack([i, i + 1, i + n + 2, i + n + 1], axis=-1).reshape(-1, 4)
    # alternate the diagonal so edges run in both directions
    flip = (np.arange(len(quads)) + np.arange(len(quads)) // n) % 2 == 1
    a = np.where(flip[:, None], quads[:, [0, 1, 3]], quads[:, [0, 1, 2]])
    b = np.where(flip[:, None], quads[:, [1, 2, 3]], quads[:, [0, 2, 3]])
    idx = np.concatenate([a, b]).astype(np.uint32)
    return MeshData(
        pos, np.tile(np.float32([0, 0, 1]), (len(pos), 1)), (pos[:, :2] / size + 0.5).astype(np.float32), idx
    )


# ----------------------------------------------------------------------------- exact against the reference


@pytest.mark.parametrize("method", ONE_PASS)
def test_compute_matches_reference_and_hardware(renderer_factory, method):
    # 18 tilted layers with an opaque quad between them, and three interpenetrating triangles
    compute, hardware = both(renderer_factory, method)
    for key, scene in (
        ("layered", layered_quads_scene(n_layers=18, order="shuffled", seed=3)),
        ("inter", interpenetrating_scene(order="shuffled", seed=1)),
    ):
        ref, mask, layers = _REFS.of(key, scene, SIZE, SIZE)
        c, h = compute.render(scene, SIZE, SIZE), hardware.render(scene, SIZE, SIZE)
        err = compare(c.image, ref, mask)
        assert err["max_abs_255"] <= 2.0, (key, err)
        assert c.stats["raster"]["compute_draws"] > 0 and c.stats["raster"]["hardware_draws"] == 0
        assert c.stats["fragments"]["overflow"] == 0 and c.stats["fragments"]["guard_abandoned"] == 0
        # the two rasterizers differ only along triangle edges, and there in a handful of pixels
        # (llvmpipe: 0-3 of 9216; the bound leaves room for another GPU's snapping of vertices)
        diff = differing(c.image, h.image)
        assert not (diff & ~mask).any(), (key, np.argwhere(diff & ~mask)[:5])
        assert diff.sum() <= 0.005 * SIZE * SIZE, (key, int(diff.sum()))
        # fragments that reached the A-buffer: how many early termination then refused depends on
        # the arrival order, which the compute path makes front to back
        fc, fh = c.stats["fragments"], h.stats["fragments"]
        reached_c = fc["stored"] + fc["early_termination_culled"]
        reached_h = fh["stored"] + fh["early_termination_culled"]
        assert abs(reached_c - reached_h) <= 0.005 * layers.sum(), (fc, fh)


def test_early_termination_with_compute(renderer_factory):
    # 20 full-screen layers of alpha 0.5 front to back: saturation culls fragments before insertion
    nodes = [
        quad_node(f"p{i}", 2.0 - 0.25 * i, colorsys.hsv_to_rgb(i / 20, 0.8, 0.9), 0.5, size=12.0) for i in range(20)
    ]
    scene = simple_scene(nodes, background=(0.05, 0.08, 0.12))
    ref, mask, _ = _REFS.of("et20", scene, 64, 64)
    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute", "threshold": 0.9})
    frame = r.render(scene, 64, 64)
    fr = frame.stats["fragments"]
    assert fr["early_termination_culled"] > 0 and fr["stored"] < 20 * 64 * 64, fr
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 0.1 * 255 + 2.0


# ----------------------------------------------------------------------------- coverage rules


@pytest.mark.parametrize("jitter", [0.0, 0.25])
def test_shared_edges_cover_every_pixel_once(renderer_factory, jitter):
    # three layers of a plane larger than the view cut into small triangles (1-6 px each, many
    # through the one-thread path): without holes or double coverage every pixel stores exactly
    # one fragment per layer and the image is that of three untessellated planes
    n, size = 64, 9.0
    layers = [(1.0, (0.9, 0.2, 0.2), 0.4), (0.0, (0.2, 0.8, 0.3), 0.5), (-1.0, (0.2, 0.3, 0.9), 0.6)]
    nodes = [
        Node(f"t{i}", Transform((0.0, 0.0, z), (0.0, 0.0, 7.0 * i)), tessellated_plane(n, size, jitter, i), unlit(c, a))
        for i, (z, c, a) in enumerate(layers)
    ]
    plain = [
        Node(f"p{i}", Transform((0.0, 0.0, z), (0.0, 0.0, 7.0 * i)), tessellated_plane(1, size, 0.0), unlit(c, a))
        for i, (z, c, a) in enumerate(layers)
    ]
    w = 80
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    frame = r.render(simple_scene(nodes), w, w)
    assert frame.stats["fragments"]["stored"] == 3 * w * w
    stats = frame.stats["raster"]["compute"]
    assert stats["large_triangles"] < stats["triangles"] // 2, stats  # the small-triangle path did most
    ref, mask, layer_count = _REFS.of("plain3", simple_scene(plain), w, w)
    assert layer_count.min() == 3
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


@pytest.mark.parametrize("samples", [1, 4])
def test_order_stage_drops_only_triangles_that_cover_no_sample(renderer_factory, samples):
    # a plane just larger than the view cut into ~0.1 px² triangles: with one sample most hold no
    # pixel centre in their snapped bounds and the order stage leaves them out, yet every sample is
    # still covered exactly once (each pixel stores one fragment; with 4 samples, whose points
    # spread over the pixel, few are left out, and the pixel's masks add up to every sample once)
    n, w = 110, 48
    node = Node("t", Transform(), tessellated_plane(n, 5.0, 0.2, 3), unlit((0.9, 0.4, 0.2), 0.5))
    pipeline = with_samples(load_pipeline("exact"), samples)
    r = renderer_factory(pipeline, method="presort_lf", method_overrides={"raster": "compute"})
    if r.samples != samples:
        pytest.skip(f"the device renders {r.samples} samples for {samples}")
    frame = r.render(simple_scene([node]), w, w)
    stats = frame.stats["raster"]["compute"]
    assert stats["triangles"] == 2 * n * n
    if samples == 1:
        assert stats["visible_triangles"] < n * n // 2, stats  # fewer than a quarter of the triangles
        assert frame.stats["fragments"]["stored"] == w * w
        return
    # each pixel's fragments cover its samples once: their masks are disjoint and fill the pixel
    m = r.method
    links = np.frombuffer(m._links.read(), np.uint64 if m.link_bytes == 8 else np.uint32)
    words = np.frombuffer(m._nodes.read(), np.uint32).reshape(-1, 8)
    for pixel in range(w * w):
        node, union, total = int(links[pixel]) & 0xFFFFFFFF, 0, 0
        while node:
            mask = int(words[node, 6]) >> 16
            union, total = union | mask, total + mask
            node = int(links[m._pixels + node]) & 0xFFFFFFFF
        assert union == total == (1 << samples) - 1, (pixel, union, total)


@pytest.mark.parametrize("samples", [1, 4])
def test_triangle_crossing_the_near_plane(renderer_factory, samples):
    # one vertex behind the camera (z=5 is the eye), two in front: clipped at the near plane. The
    # triangle is homogeneous and large (tiled: setup, bin and fine kernels), whose triangle
    # record changes layout with the sample count (raster/triangle.glsl.j2)
    tri = Node(
        "near",
        mesh=triangle_mesh((-1.5, -1.2, 0.0), (1.6, -0.8, 0.5), (0.2, 0.4, 7.0)),
        material=unlit((0.9, 0.5, 0.1), 0.6),
    )
    back = quad_node("back", -1.0, (0.1, 0.4, 0.9), 0.5, size=3.0)
    scene = simple_scene([tri, back])
    ref, mask, layers = _REFS.of("near", scene, SIZE, SIZE)
    assert (layers == 2).sum() > 150  # the clipped triangle is seen over the back quad
    compute, hardware = both(renderer_factory, "presort_lf", pipeline=with_samples(load_pipeline("exact"), samples))
    if compute.samples != samples:
        pytest.skip(f"the device renders {compute.samples} samples for {samples}")
    c, h = compute.render(scene, SIZE, SIZE), hardware.render(scene, SIZE, SIZE)
    assert c.stats["raster"]["compute"]["tile_jobs"] > 0, c.stats["raster"]
    assert compare(c.image, ref, mask)["max_abs_255"] <= 2.0
    diff = differing(c.image, h.image)
    assert not (diff & ~mask).any() and diff.sum() <= 0.005 * SIZE * SIZE


def test_back_faces_like_the_fragment_host(renderer_factory, tmp_path):
    # a quad seen from the front and one seen from the back (rotated 200 degrees), drawn with a
    # material that shows gua_normal: the compute host flips it for back faces exactly as the
    # fragment host's gl_FrontFacing does (GL's counter-clockwise front faces)
    (tmp_path / "show_normal.json").write_text(
        '{"name": "show_normal", "uniforms": {"alpha": {"type": "float", "default": 0.5}},'
        ' "visibility": [{"name": "show_normal_visibility", "source": ["void show_normal_visibility() {",'
        ' "gua_color = gua_normal * 0.5 + 0.5; gua_alpha = alpha; gua_unlit = true;", "}"]}]}'
    )

    def node(name, z, rot):
        return Node(
            name, Transform((0.4 * z, 0.0, z), (10.0, rot, 0.0)), tessellated_plane(6, 2.5, 0.2), unlit((1, 1, 1))
        )

    nodes = [node("front", 0.5, 20.0), node("back", -0.5, 200.0)]
    for n in nodes:
        n.material = MaterialInstance("show_normal", {})
    scene = simple_scene(nodes)
    compute, hardware = (
        renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": r}, material_paths=[tmp_path])
        for r in ("compute", "hardware")
    )
    c, h = compute.render(scene, SIZE, SIZE), hardware.render(scene, SIZE, SIZE)
    tris = []
    for n, world in scene.walk():
        p = n.mesh.positions @ world[:3, :3].T + world[:3, 3]
        tris.append(p[n.mesh.indices.reshape(-1, 3)])
    mask = edge_mask(np.concatenate(tris), scene.camera, SIZE, SIZE)
    diff = np.abs(c.linear - h.linear).max(axis=2)
    assert diff[~mask].max() < 1e-3, float(diff[~mask].max())
    # both quads' normals face the camera (+z, blue > 0.5) once flipped for the back face
    assert c.stats["raster"]["compute_draws"] == 2 and (c.linear[~mask][:, 2] > 0.3).sum() > 500


def test_textured_material_gets_quad_derivatives(renderer_factory, tmp_path):
    # texture() on gua_texcoords runs as textureGrad with the rasterizer's quad differences: the
    # mip level, and so the image, match the hardware's implicit LOD off the edges
    from PIL import Image

    rng = np.random.default_rng(2)
    Image.fromarray(rng.integers(0, 256, (64, 64, 4), dtype=np.uint8)).save(tmp_path / "noise.png")
    node = Node(
        "tex",
        Transform((0.0, 0.0, 0.0), (-50.0, 10.0, 0.0)),
        tessellated_plane(4, 3.0, 0.0),
        MaterialInstance("pbr_textured", {"albedo_map": str(tmp_path / "noise.png"), "alpha": 0.6}),
    )
    scene = simple_scene([node])
    scene.lights = [Light("directional", direction=(0.0, -1.0, -1.0), intensity=2.0)]
    compute, hardware = both(renderer_factory, "presort_lf")
    c, h = compute.render(scene, 64, 64), hardware.render(scene, 64, 64)
    p = node.mesh.positions @ node.transform.matrix()[:3, :3].T + node.transform.matrix()[:3, 3]
    mask = edge_mask(p[node.mesh.indices.reshape(-1, 3)], scene.camera, 64, 64)
    diff = np.abs(c.linear - h.linear).max(axis=2)[~mask]
    assert np.median(diff) < 1e-3 and diff.max() < 0.05, (float(np.median(diff)), float(diff.max()))


# ----------------------------------------------------------------------------- what it refuses


def _material(tmp_path, body: str):
    (tmp_path / "ddx.json").write_text(
        '{"name": "ddx", "uniforms": {"alpha": {"type": "float", "default": 0.5}},'
        ' "visibility": [{"name": "ddx_visibility", "source": ["void ddx_visibility() {", '
        f'"{body}", "}}"]}}]}}'
    )
    return tmp_path


def test_material_needing_derivatives_is_named(renderer_factory, tmp_path):
    mats = _material(tmp_path, "gua_color = vec3(abs(dFdx(gua_texcoords.x))); gua_alpha = alpha;")
    scene = simple_scene([Node("d", Transform(), tessellated_plane(2, 2.0, 0.0), MaterialInstance("ddx", {}))])
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"}, material_paths=[mats])
    with pytest.raises(ConfigError, match=r"material 'ddx'.*dFdx.*raster: hardware"):
        r.render(scene, 32, 32)
    # auto: that draw goes through the hardware, with the reason in the stats
    from guaca_py.raster.choice import auto_choice

    a = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "auto"}, material_paths=[mats])
    a.device.caps = type(a.caps)(**{**a.caps.as_dict(), "software": False})  # as a GPU would decide
    frame = a.render(scene, 32, 32)
    assert frame.stats["raster"]["hardware_draws"] == 1
    assert any("dFdx" in w for w in frame.stats["raster"]["why"])
    assert auto_choice(False, 1.0)[0] == "compute"


@pytest.mark.parametrize("method", ["depth_peeling", "dfb", "unsorted_blend", "weighted_blended"])
def test_methods_without_compute_path_refuse_it(renderer_factory, method):
    with pytest.raises(UnsupportedMethodError, match=f"method '{method}' cannot take transparency.raster: compute"):
        renderer_factory("exact", method=method, method_overrides={"raster": "compute"})
    # auto keeps them on the hardware, saying why
    r = renderer_factory("exact", method=method, method_overrides={"raster": "auto"})
    frame = r.render(layered_quads_scene(n_layers=4), 32, 32)
    assert frame.stats["raster"]["compute_draws"] == 0


def test_raster_setting_is_validated():
    from guaca_py.pipeline.config import pipeline_from_text

    text = "transparency: {method: presort_lf_et, raster: %s}\npasses: [geometry, light_culling, composite]\n"
    assert pipeline_from_text(text % "compute").transparency["raster"] == "compute"
    with pytest.raises(ConfigError, match=r"transparency.*raster.*hardware, compute, auto"):
        pipeline_from_text(text % "software")


# ----------------------------------------------------------------------------- storage, overflow, auto


def test_overflow_regrows_and_reports(renderer_factory, monkeypatch):
    scene = layered_quads_scene(n_layers=12, order="shuffled", seed=2)
    ref, mask, _ = _REFS.of("layered12", scene, 64, 64)
    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    cr = r.raster.compute
    cr._want = {"large": 1, "jobs": 8}  # far too small: the first attempt drops triangles and jobs
    frame = r.render(scene, 64, 64)
    assert frame.stats["regrown"] >= 1 and not frame.stats.get("warnings")
    assert cr.large_capacity > 1 and cr.job_capacity > 8
    assert frame.stats["raster"]["compute"]["large_dropped"] == 0
    mem = frame.stats["memory"]
    assert 0 < mem["raster_tile_jobs_used"] <= mem["raster_tile_jobs"] and mem["raster_vertices"] > 0
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0
    # with no re-render allowed the loss is counted and warned, and the image stays valid
    monkeypatch.setattr(compute_raster, "MAX_REGROW", 0)
    cr._want = {"large": 1, "jobs": 8}
    frame = r.render(scene, 64, 64)
    st = frame.stats["raster"]["compute"]
    assert st["large_dropped"] > 0 and any("compute raster" in w for w in frame.stats["warnings"])
    assert np.isfinite(frame.linear).all()


def test_auto_rule(renderer_factory):
    from guaca_py.raster.choice import AUTO_MAX_MEAN_AREA_PX, auto_choice, mean_projected_area

    assert auto_choice(True, 1.0)[0] == "hardware"  # software rasterizer
    assert auto_choice(False, AUTO_MAX_MEAN_AREA_PX)[0] == "compute"
    assert auto_choice(False, AUTO_MAX_MEAN_AREA_PX * 2)[0] == "hardware"
    # a 2x2 quad at distance 5 with fov 50 at 100 px: 2 triangles of half its projected area
    scene = simple_scene([quad_node("q", 0.0, (1, 1, 1), 0.5)])
    cam = scene.camera
    proj, view = cam.projection_matrix(1.0), cam.view_matrix()
    side = 2.0 / (2 * 5.0 * np.tan(np.radians(25.0))) * 100
    area = mean_projected_area(scene.nodes[0].mesh, np.eye(4), proj @ view, 100, 100)
    assert area == pytest.approx(side * side / 2, rel=1e-6)
    # on llvmpipe auto keeps every draw on the hardware and says why
    r = renderer_factory("exact", method="presort_lf_et")
    frame = r.render(scene, 32, 32)
    assert r.method.settings["raster"] == "auto"
    expected = "compute" if (not r.caps.software and area <= AUTO_MAX_MEAN_AREA_PX) else "hardware"
    assert frame.stats["raster"][f"{expected}_draws"] == 1 and "rule" in frame.stats["raster"]


def test_auto_mixes_both_rasterizers_in_one_frame(renderer_factory, monkeypatch):
    # as on a GPU with a threshold between the two sizes: small triangles go through compute, large
    # quads through the hardware, all into one A-buffer; the composite is exact either way
    from guaca_py.raster import choice

    monkeypatch.setattr(choice, "AUTO_MAX_MEAN_AREA_PX", 64.0)
    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "auto"})
    r.device.caps = dataclasses.replace(r.caps, software=False)
    fine = Node(
        "fine",
        Transform((0.0, 0.0, 0.5), (0.0, 0.0, 5.0)),
        tessellated_plane(40, 3.0, 0.2),
        unlit((0.9, 0.8, 0.1), 0.4),
    )
    plain = Node(
        "plain",
        Transform((0.0, 0.0, 0.5), (0.0, 0.0, 5.0)),
        tessellated_plane(1, 3.0, 0.0),
        unlit((0.9, 0.8, 0.1), 0.4),
    )
    layers = layered_quads_scene(n_layers=8, order="shuffled", seed=4)
    frame = r.render(simple_scene([*layers.nodes, fine], background=layers.background), 64, 64)
    info = frame.stats["raster"]
    assert info["compute_draws"] == 1 and info["hardware_draws"] == 8, info
    ref, mask, _ = _REFS.of("mixed", simple_scene([*layers.nodes, plain], background=layers.background), 64, 64)
    assert compare(frame.image, ref, mask)["max_abs_255"] <= 2.0


def test_gpu_variants_generate_compute_kernels(renderer_factory):
    # the 64-bit insertion (NVIDIA) cannot compile here: check the generated kernel as text, for
    # fragment-only built-ins that would break it and for the extension lines' place
    from guaca_py.methods import method_class
    from guaca_py.pipeline.drawlist import build_draw_list

    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    caps = dataclasses.replace(r.caps, atomic_int64=True)
    m = method_class("presort_lf_et")(dict(r.method.settings), caps)
    assert m.path == "64bit"
    draw = build_draw_list(layered_quads_scene(n_layers=2), r.materials)[0]
    cr = r.raster.compute
    cr.device.programs.program = lambda stages, smap, label: stages  # capture, do not compile
    try:
        stages = [s["compute_shader"] for s in cr._build_programs(m, draw)]
    finally:
        del cr.device.programs.program
    for template, variables in stages[1:]:
        src = r.shaders.render(template, **variables)
        code = re.sub(r"//[^\n]*", "", src)
        assert src.startswith("#version 450 core\n#extension GL_ARB_gpu_shader_int64 : require\n#extension GL_ARB")
        assert "GL_NV_shader_atomic_int64" in src
        assert "uint64_t gua_links[]" in src and "gua_submit_at(pix, z," in src
        for builtin in ("gl_FragCoord", "gl_HelperInvocation", "gl_PrimitiveID", "gl_FrontFacing", "dFdx"):
            assert builtin not in code, (template, builtin)


def random_triangles(n: int, w: int, area: float, alpha: float, seed: int, slivers: bool = True):
    """n random triangles of `area` px² (any shape, or equilateral) at z in [-0.3, 0.3], seen at w x w."""
    rng = np.random.default_rng(seed)
    px = 2.0 * 5.0 * np.tan(np.radians(25.0)) / w  # world size of a pixel at z=0
    centre = rng.uniform(-0.5, 0.5, (n, 1, 2)) * w * px
    if slivers:
        corners = rng.normal(size=(n, 3, 2))
    else:  # equilateral, turned at random
        ang = rng.uniform(0, 2 * np.pi, (n, 1)) + np.array([0.0, 2.0, 4.0]) * np.pi / 3
        corners = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    u, v = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    scale = np.sqrt(area / (0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])))
    xy = centre + (corners - corners.mean(axis=1, keepdims=True)) * scale[:, None, None] * px
    pos = np.concatenate([xy, rng.uniform(-0.3, 0.3, (n, 3, 1))], axis=2).reshape(-1, 3).astype(np.float32)
    mesh = MeshData(
        pos,
        np.tile(np.float32([0, 0, 1]), (len(pos), 1)),
        np.zeros((len(pos), 2), np.float32),
        np.arange(len(pos), dtype=np.uint32).reshape(-1, 3),
    )
    return simple_scene([Node("tris", mesh=mesh, material=unlit((0.8, 0.4, 0.2), alpha))])


@pytest.mark.parametrize("area", [3.0, 40.0])
def test_small_random_triangles_match_hardware_coverage(renderer_factory, area):
    # 2000 random triangles of a few pixels (the hairball's regime), every orientation and shape:
    # the one-thread path (and, at 40 px², the tile path too) stores the fragments the hardware
    # rasterizer makes, up to pixel centres within a rounding step of an edge
    n, w = 2000, 96
    scene = random_triangles(n, w, area, 0.3, int(area))
    compute, hardware = both(renderer_factory, "presort_lf")
    c, h = compute.render(scene, w, w), hardware.render(scene, w, w)
    sc, sh = c.stats["fragments"]["stored"], h.stats["fragments"]["stored"]
    assert sh > 0.5 * n * area and abs(sc - sh) <= 0.005 * sh, (sc, sh)
    st = c.stats["raster"]["compute"]
    # slivers of any area can have large boxes, and under perspective (corners at different
    # depths) screen areas beyond SMALL_FRAGMENTS; at 3 px² most go through the one-thread path,
    # at 40 px² nearly all through a workgroup each, some through tiles: all three paths ran
    large = st["large_triangles"]
    assert (0 < large < 0.15 * n) if area < 20 else (large > 0.9 * n), st
    assert 0 < st["tiled_triangles"] < st["large_triangles"] and st["tile_jobs"] > 0, st
    assert differing(c.image, h.image).mean() < 0.05


@pytest.mark.parametrize("ballot", [True, False])
@pytest.mark.parametrize("method", ["presort_lf_et", "presort_lf_merge2_et", "post_sort"])
def test_stored_equals_the_lists_with_many_fragments_per_thread(renderer_factory, method, ballot):
    # one compute invocation reserves nodes for its triangle and submits many fragments, some
    # stored, some refused by early termination: the derived 'stored' (reserved nodes left over
    # count as unlinked) must still equal the nodes the lists hold, with and without ballots
    from test_counters import _linked_nodes

    scene = random_triangles(3000, 64, 12.0, 0.6, 11)
    disable = () if ballot else ("shader_ballot",)
    r = renderer_factory(
        "exact", method=method, method_overrides={"raster": "compute", "threshold": 0.9}, disable=disable
    )
    fr = r.render(scene, 64, 64).stats["fragments"]
    assert fr["stored"] == _linked_nodes(r.method), fr
    if method != "post_sort":
        assert fr["et_dropped"] + fr["et_culled"] > 0, fr


def test_command_line_set_and_info(capsys, tmp_path):
    import json

    from guaca_py.cli import main

    assert main(["info"]) == 0
    info = capsys.readouterr().out
    assert "transparent raster (raster: auto):" in info and "compute triangle order (raster_order: auto): depth" in info
    args = ["render", "--pipeline", "exact", "--width", "48", "--height", "40", "--out", str(tmp_path / "o.png")]
    assert main([*args, "--set", "raster=compute", "--stats", str(tmp_path / "s.json")]) == 0
    out = capsys.readouterr().out
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["raster"]["setting"] == "compute" and stats["raster"]["compute_draws"] > 0
    assert "transparent raster (compute)" in out and stats["memory"]["raster_vertices"] > 0
    # the default method has early termination: depth order; the setting overrides it
    assert stats["raster"]["compute"]["order"] == "depth" and "triangle order depth" in out
    assert main([*args, "--set", "raster=compute", "--set", "raster_order=tile"]) == 0
    assert "triangle order tile" in capsys.readouterr().out
    assert main([*args, "--method", "depth_peeling", "--set", "raster=compute"]) == 2
    assert "depth_peeling" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslangValidator (glslang-tools) not installed")
@pytest.mark.parametrize("samples", [1, 4])
@pytest.mark.parametrize("method", ["presort_lf_et", "presort_lf_merge2_et"])
def test_gpu_variants_pass_the_reference_compiler(renderer_factory, tmp_path, method, samples):
    # the NVIDIA variants (64-bit insertion, subgroup ballots) of every kernel, with every built-in
    # material made transparent, at one and at four samples (the list walk differs per kernel and
    # sample count), through Khronos' reference compiler (this device cannot compile them)
    import subprocess

    from guaca_py.antialiasing import with_samples
    from guaca_py.methods import method_class
    from guaca_py.pipeline.drawlist import build_draw_list
    from guaca_py.renderer import method_settings

    pipeline = with_samples(load_pipeline("exact"), samples, "test")
    r = renderer_factory(pipeline, method=method, method_overrides={"raster": "compute"})
    extra = {"shader_ballot": True} if hasattr(r.caps, "shader_ballot") else {}
    caps = dataclasses.replace(r.caps, atomic_int64=True, **extra)
    m = method_class(method)(method_settings(method, {"raster": "compute"}), caps)
    m.aa_samples = r.samples
    cr = r.raster.compute
    try:
        cr.device.programs.program = lambda stages, smap, label: stages  # capture, do not compile
        mats = {
            "pbr": {"alpha": 0.5},
            "fresnel_glass": {},
            "lens_fade_out": {},
            "pbr_textured": {},
            "unlit": {"alpha": 0.5},
        }
        scene = simple_scene([quad_node(k, 0.0, (1, 1, 1), 0.5) for k in mats])
        for node in scene.nodes:
            node.material = MaterialInstance(node.name, mats[node.name])
        draws = build_draw_list(scene, r.materials)
        stages = [s["compute_shader"] for d in draws for s in cr._build_programs(m, d)]
    finally:
        del cr.device.programs.program
    assert all(d.transparent for d in draws) and len(stages) == 4 * len(mats)
    stages += [
        *(("raster/args.comp.j2", {**cr._raster_vars(), "args_mode": m}) for m in (1, 2)),
        *(("raster/order.comp.j2", {**cr._raster_vars(), "order_mode": m}) for m in (0, 1, 3)),
        ("raster/order_scan.comp.j2", cr._raster_vars()),
    ]
    for i, (template, variables) in enumerate(stages):
        path = tmp_path / f"k{i}.comp"
        path.write_text(r.shaders.render(template, **variables))
        run = subprocess.run(["glslangValidator", "-S", "comp", str(path)], capture_output=True, text=True)
        assert run.returncode == 0, (template, run.stdout[-2000:])


def test_a_triangles_fragments_get_neighbouring_nodes(renderer_factory):
    # the one-thread path reserves a run of nodes per triangle: each small triangle's fragments
    # (neighbouring pixels) sit in consecutive nodes, as a fragment shader warp's allocation puts
    # them (fragment-by-fragment allocation spread them over the pool and made the H100's list
    # walks and composite several times slower than with hardware-rasterized lists)
    scene = random_triangles(1500, 64, 6.0, 0.3, 5, slivers=False)
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    r.raster.compute.small_fragments = 1e9  # all through the one-thread path, whatever their area
    frame = r.render(scene, 64, 64)
    m = r.method
    links = np.frombuffer(m._links.read(), dtype=np.uint64 if m.link_bytes == 8 else np.uint32).astype(np.int64)
    links &= 0xFFFFFFFF
    ties = np.frombuffer(m._nodes.read(), dtype=np.uint32).reshape(-1, 8)[:, 7]
    nodes = []
    for n in links[: m._pixels].tolist():
        while n:
            nodes.append(n)
            n = int(links[m._pixels + n])
    nodes = np.array(nodes)
    assert len(nodes) == frame.stats["fragments"]["stored"] > 1500
    prim = ties[nodes] & 0xFFFFF
    order = np.lexsort((nodes, prim))
    prim, nodes = prim[order], nodes[order]
    first = np.r_[True, prim[1:] != prim[:-1]]
    span = np.maximum.reduceat(nodes, np.flatnonzero(first)) - nodes[first] + 1
    count = np.diff(np.r_[np.flatnonzero(first), len(nodes)])
    assert frame.stats["raster"]["compute"]["large_triangles"] == 0
    assert len(count) > 1000 and (span == count).all()


@pytest.mark.parametrize("method", ["presort_lf_et", "presort_lf"])
def test_triangles_are_taken_in_depth_order(renderer_factory, method):
    # one mesh of 24 full-screen layers listed back to front: the setup stage takes them front to
    # back with early termination (the saturation depth then culls the farther ones), back to
    # front without (each insertion stops at the list head); layers outside the frustum are left out
    n = 24
    quads = [tessellated_plane(1, 12.0, 0.0) for _ in range(n)]
    zs = np.linspace(-3.0, 2.0, n)
    pos = np.concatenate([q.positions + np.float32([0, 0, z]) for q, z in zip(quads, zs)])
    pos = np.concatenate([pos, quads[0].positions + np.float32([0, 0, 9.0])])  # behind the camera
    idx = np.concatenate([q.indices + 4 * i for i, q in enumerate([*quads, quads[0]])]).astype(np.uint32)
    mesh = MeshData(pos, np.tile(np.float32([0, 0, 1]), (len(pos), 1)), np.zeros((len(pos), 2), np.float32), idx)
    scene = simple_scene([Node("stack", mesh=mesh, material=unlit((0.7, 0.3, 0.2), 0.5))])
    overrides = {"raster": "compute", "threshold": 0.9, "raster_order": "depth"}
    r = renderer_factory("exact", method=method, method_overrides=overrides)
    frame = r.render(scene, 32, 32)
    st = frame.stats["raster"]["compute"]
    assert st["visible_triangles"] == 2 * n, st
    order = np.frombuffer(r.raster.compute._order.read(), dtype=np.uint32)[: 2 * n]
    layer = order // 2  # two triangles per layer; layer 0 is the farthest
    steps = np.diff(layer.astype(int))
    assert (steps <= 0).all() if method == "presort_lf_et" else (steps >= 0).all(), layer
    if r.caps.software and method == "presort_lf_et":  # llvmpipe runs workgroups in order
        assert frame.stats["fragments"]["stored"] <= 6 * 32 * 32, frame.stats["fragments"]


@pytest.mark.parametrize(
    ("method", "order", "mesh_order"),
    [
        ("post_sort", "mesh", True),
        ("post_merge16", "mesh", True),
        ("presort_lf", "depth", False),
        ("presort_lf", "mesh", True),
        ("post_sort", "depth", False),
    ],
)
def test_raster_order_mesh_and_depth(renderer_factory, method, order, mesh_order):
    # 24 full-screen layers listed front to back: index order keeps them so, depth order without
    # early termination takes them back to front
    n = 24
    quads = [tessellated_plane(1, 12.0, 0.0) for _ in range(n)]
    pos = np.concatenate([q.positions + np.float32([0, 0, z]) for q, z in zip(quads, np.linspace(2.0, -3.0, n))])
    idx = np.concatenate([q.indices + 4 * i for i, q in enumerate(quads)]).astype(np.uint32)
    mesh = MeshData(pos, np.tile(np.float32([0, 0, 1]), (len(pos), 1)), np.zeros((len(pos), 2), np.float32), idx)
    scene = simple_scene([Node("stack", mesh=mesh, material=unlit((0.7, 0.3, 0.2), 0.5))])
    r = renderer_factory("exact", method=method, method_overrides={"raster": "compute", "raster_order": order})
    frame = r.render(scene, 32, 32)
    assert frame.stats["raster"]["compute"]["visible_triangles"] == 2 * n
    layer = np.frombuffer(r.raster.compute._order.read(), dtype=np.uint32)[: 2 * n] // 2
    steps = np.diff(layer.astype(int))
    assert (steps >= 0).all() if mesh_order else (steps <= 0).all(), layer
    assert frame.stats["fragments"]["stored"] == n * 32 * 32


def test_auto_takes_compute_for_every_size_where_the_method_asks(renderer_factory, monkeypatch):
    # presort_cs_et on a GPU took the spin lock for the compute kernels: `auto` then sends large
    # triangles there too rather than into a fragment-shader spin lock
    from guaca_py.pipeline.drawlist import build_draw_list

    r = renderer_factory("exact", method="presort_cs_et")
    scene = simple_scene([quad_node("big", 0.0, (0.5, 0.5, 0.5), 0.5, size=12.0)])
    draw = next(d for d in build_draw_list(scene, r.materials) if d.transparent)
    monkeypatch.setattr(r.device, "caps", dataclasses.replace(r.caps, software=False))
    monkeypatch.setattr(r.method, "auto_compute_reason", "spin lock for compute kernels")
    assert r.raster.choose(types.SimpleNamespace(method=r.method), draw) == ("compute", "spin lock for compute kernels")
    monkeypatch.setattr(r.method, "auto_compute_reason", None)  # the area rule: a screen-filling quad
    frame = types.SimpleNamespace(method=r.method, projection=np.eye(4), view=np.eye(4), width=1024, height=1024)
    kind, why = r.raster.choose(frame, draw)
    assert kind == "hardware" and "area" in why, (kind, why)


@pytest.mark.parametrize(
    ("method", "expected"),
    [
        ("presort_lf_et", "depth"),
        ("presort_cs_et", "depth"),
        ("presort_lf", "tile"),
        ("post_sort", "tile"),
        ("post_merge16", "tile"),
    ],
)
def test_auto_raster_order_is_depth_with_early_termination_else_tile(renderer_factory, method, expected):
    # the measured rule (docs/decisions.md, 2026-11-23 "the compute rasterizer's triangle order"): early
    # termination culls most in depth order, the others walk and composite fastest over tile-ordered pools
    r = renderer_factory("exact", method=method)
    assert r.method.raster_order(1024 * 1024) == expected
    # past 2048² tile order's locality outweighs early termination's culling (raster/choice.py)
    assert r.method.raster_order(2048 * 2048) == expected
    assert r.method.raster_order(2048 * 2049) == "tile"
    r2 = renderer_factory("exact", method=method, method_overrides={"raster_order": "mesh"})
    assert r2.method.raster_order() == "mesh"


def _morton16(ndc: np.ndarray) -> np.ndarray:
    """Morton key of the 16 x 16 screen tile of NDC points (order.comp.j2's tile order)."""
    t = np.minimum(np.floor((np.clip(ndc, -1, 1) * 0.5 + 0.5) * 16), 15).astype(int)
    key = np.zeros(len(t), int)
    for bit in range(4):
        key |= ((t[:, 0] >> bit) & 1) << (2 * bit) | ((t[:, 1] >> bit) & 1) << (2 * bit + 1)
    return key


@pytest.mark.parametrize(
    ("method", "large"),
    [("presort_lf", False), ("presort_lf_et", False), ("post_sort", False), ("presort_lf_et", True)],
)
def test_tile_order_runs_screen_tiles_one_after_another(renderer_factory, monkeypatch, method, large):
    # small quads in a 3 x 3 grid of screen places, three depths each, listed depth-major: the tile
    # order takes them place by place (Morton order of their tiles), by the method's depth
    # direction within a place (front to back with early termination, back to front without)
    # places at screen tile centres, each quad scaled along its eye ray to project the same there
    places = [-1 + 0.125 * (i + 0.5) for i in (3, 8, 12)]
    zs = (1.0, 0.0, -1.0)
    nodes_pos, tris = [], []
    for zi, z in enumerate(zs):
        s = (5.0 - z) * np.tan(np.radians(25.0))  # NDC to world at this depth (camera at z = 5)
        for y in places:
            for x in places:
                # 2.56 px wide: each covers pixel centres (the order stage drops triangles that cover none)
                q = np.float32([[-0.04, -0.04, 0], [0.04, -0.04, 0], [0.04, 0.04, 0], [-0.04, 0.04, 0]]) * s
                nodes_pos.append(q + np.float32([x * s, y * s, z]))
                tris.append((zi, x, y, z))
    pos = np.concatenate(nodes_pos)
    idx = np.concatenate([np.uint32([[0, 1, 2], [0, 2, 3]]) + 4 * i for i in range(len(nodes_pos))]).astype(np.uint32)
    mesh = MeshData(pos, np.tile(np.float32([0, 0, 1]), (len(pos), 1)), np.zeros((len(pos), 2), np.float32), idx)
    scene = simple_scene([Node("grid", mesh=mesh, material=unlit((0.7, 0.3, 0.2), 0.5))])
    order_setting = "tile"
    if large:  # a "large" frame (raster/choice.py's bound lowered to this test's): auto takes tile order
        monkeypatch.setattr(choice, "LARGE_FRAME_PIXELS", 32 * 32)
        order_setting = "auto"
    r = renderer_factory("exact", method=method, method_overrides={"raster": "compute", "raster_order": order_setting})
    frame = r.render(scene, 64, 64)
    assert frame.stats["raster"]["compute"]["order"] == "tile"
    n = 2 * len(nodes_pos)
    assert frame.stats["raster"]["compute"]["visible_triangles"] == n
    order = np.frombuffer(r.raster.compute._order.read(), dtype=np.uint32)[:n]
    # each triangle's tile from its corners' NDC centroid, as the kernel takes it
    vp = scene.camera.projection_matrix(1.0) @ scene.camera.view_matrix()
    clip = np.c_[pos, np.ones(len(pos))] @ vp.T
    ndc = clip[:, :2] / clip[:, 3:4]
    keys = _morton16(ndc[idx].mean(axis=1))[order]
    assert (np.diff(keys) >= 0).all(), keys
    assert len(set(keys.tolist())) == 9  # nine places, nine tiles
    depth_rank = np.array([tris[t // 2][0] for t in order])  # 0 nearest
    for k in set(keys.tolist()):
        steps = np.diff(depth_rank[keys == k])
        assert (steps >= 0).all() if method == "presort_lf_et" else (steps <= 0).all(), depth_rank[keys == k]
    assert frame.stats["fragments"]["overflow"] == 0


def test_stage_profile_reports_each_stage(renderer_factory, monkeypatch):
    # GUACA_RASTER_STAGES=1 (profiling only: reading the timestamps waits for the GPU) adds the GPU
    # time of each compute-raster stage to the frame's stats; off by default
    scene = layered_quads_scene(n_layers=4, order="shuffled", seed=2)
    plain = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    assert "stage_ms" not in plain.render(scene, 48, 48).stats["raster"]["compute"]
    monkeypatch.setenv("GUACA_RASTER_STAGES", "1")
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    for _ in range(2):  # marks do not pile up from frame to frame
        stages = r.render(scene, 48, 48).stats["raster"]["compute"]["stage_ms"]
        assert set(stages) == {"between_draws", "vertex", "order", "setup", "bin", "fine"}, stages
        assert all(v >= 0.0 for v in stages.values())
    assert len(r.raster.compute._stages._marks) == 0
    # the same from the Python API, on and off again, without the environment
    monkeypatch.delenv("GUACA_RASTER_STAGES")
    plain.raster.compute.profile_stages(True)
    assert set(plain.render(scene, 48, 48).stats["raster"]["compute"]["stage_ms"]) == set(stages)
    plain.raster.compute.profile_stages(False)
    assert "stage_ms" not in plain.render(scene, 48, 48).stats["raster"]["compute"]


def test_triangles_of_many_fragments_go_to_a_workgroup(renderer_factory):
    # boxes well under SMALL_AREA, but 30 px² each: a workgroup shades their fragments side by
    # side instead of one thread one after another; the lists (and image) are the same either way
    scene = random_triangles(400, 64, 30.0, 0.4, 9, slivers=False)
    by_area, by_box = (
        renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"}) for _ in range(2)
    )
    by_box.raster.compute.small_fragments = 1e9
    a, b = by_area.render(scene, 64, 64), by_box.render(scene, 64, 64)
    assert a.stats["raster"]["compute"]["large_triangles"] > 0.9 * 400
    assert b.stats["raster"]["compute"]["large_triangles"] == 0
    assert a.stats["fragments"]["stored"] == b.stats["fragments"]["stored"] > 400 * 25
    assert (a.image == b.image).all()


def test_a_repeated_frame_sends_only_what_differs_between_draws(renderer_factory, monkeypatch):
    # The CPU cost of a frame paces an application's loop on a fast GPU: a frame of an unchanged
    # scene must not write again what its kernels already hold (camera, per-call values), only the
    # values that differ from one draw to the next (transform, index, material instance)
    import moderngl

    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    n = 6
    scene = layered_quads_scene(n_layers=n, order="shuffled", seed=2)
    for _ in range(2):
        first = r.render(scene, 64, 64)
    written = []
    write = moderngl.Uniform.write  # the `value` setter writes through it too
    monkeypatch.setattr(moderngl.Uniform, "write", lambda u, data: (written.append(u.name), write(u, data))[1])
    again = r.render(scene, 64, 64)
    assert np.array_equal(again.image, first.image)
    assert again.stats["raster"]["compute_draws"] == n
    camera = {"gua_view_matrix", "gua_projection_matrix", "gua_inverse_view_projection", "gua_camera_position"}
    assert not camera & set(written), sorted(set(written))
    # per draw nothing: its transform, counts, depth range, index and material values are in its record
    # (raster/draw_record.py); per frame: a few
    assert len(written) <= 8, sorted(written)
    # a moved camera: each kernel gets the new camera once, not once per draw
    scene.camera.position = tuple(np.add(scene.camera.position, (0.01, 0.0, 0.0)))
    written.clear()
    r.render(scene, 64, 64)
    assert 0 < written.count("gua_view_matrix") <= 4, written.count("gua_view_matrix")


def test_draw_records_keep_their_room(renderer_factory):
    # every draw's record (raster/draw_record.py) in one buffer a call: it grows to the largest call and stays
    # (a view or frame of fewer draws made it anew, so views of one call reported different allocations)
    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    many = simple_scene([quad_node(f"q{i}", -0.1 * i, (1, 0.5, 0.2), 0.5) for i in range(12)])
    few = simple_scene([quad_node("q0", 0.0, (1, 0.5, 0.2), 0.5)])
    sizes = [r.render(scene, 32, 32).stats["memory"]["raster_draw_records"] for scene in (many, few, many)]
    assert sizes[0] >= 12 * 256 and sizes == [sizes[0]] * 3


def test_a_repeated_frame_looks_up_no_raster_kernel_and_a_new_method_gets_its_own(renderer_factory, monkeypatch):
    # the kernels of a material are remembered per method state (the program cache's key freezes every
    # template variable, some hundred calls a material and frame); another method must not get them
    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    scene = layered_quads_scene(n_layers=4)
    for _ in range(2):
        r.render(scene, 64, 64)
    library = r.raster.compute.device.programs
    looked_up = []
    real = library.program
    monkeypatch.setattr(
        library,
        "program",
        lambda stages, *a, **k: (looked_up.extend(t for t, _ in stages.values()), real(stages, *a, **k))[1],
    )
    r.render(scene, 64, 64)
    assert not [t for t in looked_up if t.startswith("raster/")], looked_up
    r.set_method("presort_lf_merge2_et", {"raster": "compute"})  # another insertion: other kernels
    frame = r.render(scene, 64, 64)
    assert {"raster/vertex.comp.j2", "raster/setup.comp.j2", "raster/fine.comp.j2"} <= set(looked_up)
    assert frame.stats["raster"]["compute_draws"] == 4 and frame.stats["fragments"]["stored"] > 0


def test_a_still_scene_sends_its_draw_records_once(renderer_factory, monkeypatch):
    # the records of a frame like the last are what the buffer holds: not written (nor orphaned) again
    import moderngl

    r = renderer_factory("exact", method="presort_lf_et", method_overrides={"raster": "compute"})
    scene = layered_quads_scene(n_layers=3)
    first = r.render(scene, 32, 32)
    staging = r.raster.compute._records._staging  # UploadBuffer: what the CPU writes, copied on the GPU
    writes = []
    write = moderngl.Buffer.write
    monkeypatch.setattr(
        moderngl.Buffer, "write", lambda b, *a, **k: (writes.append(b is staging), write(b, *a, **k))[1]
    )
    again = r.render(scene, 32, 32)
    assert not any(writes) and np.array_equal(again.image, first.image)
    scene.nodes[0].transform.translation = (0.05, 0.0, scene.nodes[0].transform.translation[2])
    moved = r.render(scene, 32, 32)
    assert writes.count(True) == 1 and not np.array_equal(moved.image, first.image)
