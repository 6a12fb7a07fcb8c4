"""antialiasing.merge: adjacent: one node per pixel and surface where sub-pixel triangles would each make one.

The triangle covering a pixel centre takes the samples its same-facing edge neighbours cover there
into its node, and they make no fragment in that pixel (raster/triangle.glsl.j2, gua_neighbour_ok).
Every sample stays covered exactly once, so one-coloured surfaces render exactly as without merging.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from guaca_py.antialiasing import with_settings
from guaca_py.errors import ConfigError
from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.raster.adjacency import NO_NEIGHBOUR, edge_apexes
from guaca_py.reference import origin_camera, quad_mesh, rmse_255, supersampled, unlit
from guaca_py.scene.graph import Light, MaterialInstance, MeshData, Node, Scene, Transform

EXACT = load_pipeline("exact")
COMPUTE = {"raster": "compute"}  # merging happens in the compute rasterizer (llvmpipe's auto takes the hardware)


def sphere_mesh(subdivisions: int, radius: float = 1.0) -> MeshData:
    """An icosphere: a closed surface of nearly equal triangles, sub-pixel at the tests' sizes."""
    s = trimesh.creation.icosphere(subdivisions, radius=radius)
    positions = np.asarray(s.vertices, dtype=np.float32)
    return MeshData(
        positions=positions,
        normals=positions / np.linalg.norm(positions, axis=1, keepdims=True),
        texcoords=np.zeros((len(s.vertices), 2), dtype=np.float32),
        indices=np.asarray(s.faces, dtype=np.uint32),
        name=f"icosphere{subdivisions}",
    )


def ramp_grid(columns: int = 30, rows: int = 6) -> MeshData:
    """A flat grid whose columns widen geometrically: triangles from far below a pixel to far above
    the setup stage's size, side by side (merging stops where a neighbour goes to the bin stage)."""
    xs = np.cumsum(np.concatenate([[0.0], 0.004 * 1.2 ** np.arange(columns)]))
    xs = xs / xs[-1] * 2.4 - 1.2
    ys = np.linspace(-0.6, 0.6, rows + 1)
    gx, gy = np.meshgrid(xs, ys)
    positions = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1).astype(np.float32)
    w = columns + 1
    quads = [
        (r * w + c, r * w + c + 1, (r + 1) * w + c + 1, (r + 1) * w + c) for r in range(rows) for c in range(columns)
    ]
    indices = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], dtype=np.uint32)
    normals = np.tile(np.array([[0.0, 0.0, 1.0]], dtype=np.float32), (len(positions), 1))
    texcoords = np.zeros((len(positions), 2), dtype=np.float32)
    return MeshData(positions=positions, normals=normals, texcoords=texcoords, indices=indices, name="ramp")


def spheres(material, opaque: bool = False) -> Scene:
    """Two transparent spheres of small triangles and a grid of growing ones behind them, overlapping on
    screen but not in space (where surfaces intersect, a merged node orders all its samples by one
    depth); an opaque quad."""
    nodes = [
        Node("left", Transform((-0.7, 0.0, 0.0)), sphere_mesh(4), material((1.0, 0.5, 0.2))),
        Node("right", Transform((0.8, 0.3, -2.0)), sphere_mesh(4), material((0.2, 0.6, 1.0))),
        Node(
            "ramp",
            Transform((0.0, -0.8, -4.5), (-30.0, 20.0, 10.0), (3.2, 3.2, 1.0)),
            ramp_grid(),
            material((0.3, 0.9, 0.4)),
        ),
    ]
    if opaque:
        nodes.append(Node("wall", Transform((0.5, -0.6, -2.5)), quad_mesh(1.2, 0.8), unlit((0.9, 0.9, 0.8))))
    light = Light("directional", direction=(-0.4, -0.6, -1.0), intensity=3.0)
    return Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), lights=[light], nodes=nodes)


def flat(color) -> MaterialInstance:
    return unlit(color, 0.5)


def lit(color) -> MaterialInstance:
    return MaterialInstance("pbr", {"albedo": list(color), "roughness": 0.4, "alpha": 0.5})


@pytest.fixture(scope="module")
def render(renderer_factory):
    """(image, stats) of a scene at `samples`, merged or not, through the compute rasterizer."""
    made = {}

    def run(scene: Scene, size: int, samples: int, merge: str, pipeline=EXACT):
        cfg = with_settings(pipeline, {"samples": samples, "merge": merge}, "test")
        key = (cfg.source, cfg.name, tuple(sorted(cfg.antialiasing.items())))
        if key not in made:
            made[key] = renderer_factory(cfg, method="presort_lf_et", method_overrides=COMPUTE)
        frame = made[key].render(scene, size, size)
        return frame.linear, frame.stats

    return run


def test_one_coloured_surfaces_render_as_without_merging(render):
    """Each sample covered once: no lost sample (background would show) and no doubled one (a darker
    blend), across both spheres' silhouettes, where front and back faces meet and must not merge."""
    scene = spheres(flat)
    exact, s_exact = render(scene, 72, 4, "off")
    merged, s_merged = render(scene, 72, 4, "adjacent")
    _, s_one = render(scene, 72, 1, "off")
    assert s_merged["antialiasing"]["merge"] == "adjacent" and "merge" not in s_exact["antialiasing"]
    assert np.abs(merged - exact).max() < 1e-6
    one, four, fewer = (s["fragments"]["stored"] for s in (s_one, s_exact, s_merged))
    assert four > 2.2 * one  # sub-pixel triangles: about one node per triangle and pixel at 4 samples
    assert one <= fewer <= 0.75 * four, (one, four, fewer)


@pytest.mark.parametrize("method", ["presort_lf", "presort_lf_merge2_et", "presort_cs_et", "post_sort", "post_merge16"])
def test_every_method_with_coverage_takes_merged_nodes(renderer_factory, method):
    """Merging happens in the rasterizer, before any method's insertion: the same image with fewer nodes."""
    scene, out = spheres(flat), {}
    for merge in ("off", "adjacent"):
        cfg = with_settings(EXACT, {"samples": 4, "merge": merge}, "test")
        frame = renderer_factory(cfg, method=method, method_overrides=COMPUTE).render(scene, 48, 48)
        out[merge] = frame.linear, frame.stats["fragments"]["stored"]
    assert np.abs(out["adjacent"][0] - out["off"][0]).max() < 1e-6
    assert out["adjacent"][1] < 0.8 * out["off"][1], (out["adjacent"][1], out["off"][1])


def test_lit_surfaces_keep_the_edge_antialiasing(render, renderer_factory):
    """Merged samples take the shading of the triangle at the pixel centre, interpolated at the centroid of
    the node's samples (here: sub-pixel triangles of lit spheres, whose normals turn inside a pixel):
    measured against the 8x8-supersampled exact frame, the edge error stays that of unmerged samples."""
    scene, size = spheres(lit), 64
    linear = pipeline_from_text(
        "transparency: {method: presort_lf_et, threshold: 0.999}\npasses: [geometry, light_culling, composite]\n",
        "linear.yaml",
    )
    ref_r = renderer_factory(linear, method="presort_lf", method_overrides={"raster": "hardware"})
    ref = supersampled(ref_r, scene, size, size, 8)
    edges = ref.spread > 0.05
    err = {
        (n, m): rmse_255(render(scene, size, n, m, linear)[0], ref.image, edges)
        for n, m in ((1, "off"), (4, "off"), (4, "adjacent"))
    }
    assert edges.sum() > 200
    assert err[4, "off"] * 2 <= err[1, "off"], err
    # llvmpipe, 64²: 9.21 at 1 sample, 3.669 unmerged, 3.670 merged (in 1/255); with the merged node
    # shaded at the pixel centre instead of its samples' centroid it was 3.75
    assert err[4, "adjacent"] <= 1.1 * err[4, "off"] and err[4, "adjacent"] * 2 <= err[1, "off"], err


def test_merging_beside_opaque_draws(render):
    """Merged samples take the opaque test at the merging triangle's plane: behind the opaque quad they
    are hidden as unmerged ones are; only where a sphere crosses the quad may a sample differ."""
    scene = spheres(flat, opaque=True)
    exact, s_exact = render(scene, 64, 4, "off")
    merged, s_merged = render(scene, 64, 4, "adjacent")
    assert s_merged["fragments"]["stored"] < 0.8 * s_exact["fragments"]["stored"]
    diff = np.abs(merged - exact).max(axis=-1)
    assert (diff > 1e-6).sum() <= 0.005 * diff.size and diff.max() < 0.1, ((diff > 1e-6).sum(), diff.max())


def test_a_sharper_crease_limit_merges_less(render):
    """merge_crease_deg: a folded strip (every second edge bent by 40 degrees) merges across its flat
    edges only below that limit; each frame still covers every sample once (one colour: the same image)."""
    xs = np.linspace(-1.0, 1.0, 41)
    zs = np.where(np.arange(41) % 2 == 0, 0.0, 0.02)  # a zigzag: neighbouring faces meet at ~44 degrees
    ys = np.array([-0.8, 0.8])
    positions = np.array([[x, y, z] for y in ys for x, z in zip(xs, zs)], dtype=np.float32)
    quads = [(c, c + 1, 41 + c + 1, 41 + c) for c in range(40)]
    indices = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], dtype=np.uint32)
    mesh = MeshData(
        positions=positions,
        normals=np.tile(np.array([[0.0, 0.0, 1.0]], dtype=np.float32), (len(positions), 1)),
        texcoords=np.zeros((len(positions), 2), dtype=np.float32),
        indices=indices,
        name="zigzag",
    )
    scene = Scene(
        camera=origin_camera(),
        background=(0.05, 0.08, 0.12),
        nodes=[
            Node("zigzag", Transform((0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)), mesh, flat((0.8, 0.3, 0.3)))
        ],
    )
    exact, s_exact = render(scene, 48, 4, "off")
    stored = {}
    for deg in (15.0, 60.0):
        pipeline = with_settings(EXACT, {"merge_crease_deg": deg}, "test")
        merged, s = render(scene, 48, 4, "adjacent", pipeline)
        stored[deg] = s["fragments"]["stored"]
        assert np.abs(merged - exact).max() < 1e-6
    assert stored[60.0] < stored[15.0] <= s_exact["fragments"]["stored"], (stored, s_exact["fragments"]["stored"])


def test_neighbour_buffers_reported_and_held_to_the_storage_rule(render, renderer_factory, monkeypatch):
    """The edge neighbours take 12 bytes a triangle, once per mesh content (the two spheres share one), in
    stats["memory"]; a mesh whose neighbours would pass the device's storage rule is refused by name."""
    from guaca_py.errors import LimitError

    scene = spheres(flat)
    _, stats = render(scene, 32, 4, "adjacent")
    sphere, ramp = scene.nodes[0].mesh, scene.nodes[2].mesh
    assert stats["memory"]["raster_adjacency"] == 12 * (sphere.triangle_count + ramp.triangle_count)
    # 20000 triangles on 4 vertices: every other buffer of the frame fits 0.1 MB, the 240 kB of neighbours not
    quad = quad_mesh(1.0, 1.0)
    many = MeshData(quad.positions, quad.normals, quad.texcoords, np.tile(quad.indices, (10000, 1)), "many")
    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "0.1")
    r = renderer_factory(with_settings(EXACT, {"samples": 4, "merge": "adjacent"}, "test"), method_overrides=COMPUTE)
    with pytest.raises(LimitError, match="antialiasing.merge") as err:
        r.render(Scene(camera=origin_camera(), nodes=[Node("many", Transform(), many, flat((1.0, 0.0, 0.0)))]), 16, 16)
    assert "12 bytes a triangle" in str(err.value)


def test_hardware_rasterized_draws_are_named_unmerged(renderer_factory):
    cfg = with_settings(EXACT, {"samples": 4, "merge": "adjacent"}, "test")
    r = renderer_factory(cfg, method="presort_lf_et", method_overrides={"raster": "hardware"})
    stats = r.render(spheres(flat), 32, 32).stats
    assert any("antialiasing.merge: adjacent applies to compute-rasterized draws" in w for w in stats["warnings"])


def test_merge_setting_validated_and_idle_at_one_sample(renderer_factory):
    with pytest.raises(ConfigError) as err:
        pipeline_from_text("antialiasing: {samples: 4, merge: yes}\n", "p.yaml")
    assert err.value.line == 1 and "merge" in str(err.value) and "off, adjacent" in str(err.value)
    with pytest.raises(ConfigError, match=r"merge_crease_deg.*must be in \(0, 180\], got 0"):
        pipeline_from_text("antialiasing: {samples: 4, merge: adjacent, merge_crease_deg: 0}\n", "p.yaml")
    r = renderer_factory(with_settings(EXACT, {"merge": "adjacent"}, "test"), method_overrides=COMPUTE)
    assert not r.device.antialiasing.merge  # nothing to merge with one sample per pixel
    assert "merge" not in r.render(spheres(flat), 16, 16).stats["antialiasing"]


def test_edge_apexes_against_a_brute_force_search():
    """Neighbours only across manifold, consistently wound edges."""
    s = trimesh.creation.icosphere(2)
    faces = np.asarray(s.faces, dtype=np.int64)
    # a boundary (one triangle removed), a flipped triangle, and a third triangle on one edge
    faces = np.delete(faces, 0, axis=0)
    faces[5] = faces[5][::-1]
    a, b = faces[10][1], faces[10][2]
    faces = np.vstack([faces, [b, a, len(s.vertices)]])
    got = edge_apexes(faces)
    for t, f in enumerate(faces):
        for j in range(3):
            a, b = f[(j + 1) % 3], f[(j + 2) % 3]
            twins = [u for u, g in enumerate(faces) if any(g[k] == b and g[(k + 1) % 3] == a for k in range(3))]
            same = [u for u, g in enumerate(faces) if any(g[k] == a and g[(k + 1) % 3] == b for k in range(3))]
            want = NO_NEIGHBOUR
            if len(twins) == 1 and len(same) == 1:
                want = next(v for v in faces[twins[0]] if v not in (a, b))
            assert got[t, j] == want, (t, j)
    assert (got == NO_NEIGHBOUR).sum() >= 6  # the hole's three edges, the flipped triangle's, the third one's
