"""Tiled light culling: the light grid against the exact float64 CPU overlap, images with culling on/off, config, debug views."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import quad_node, simple_scene, unit_quad

from guaca_py import ConfigError, DeviceError, pipeline_from_text
from guaca_py.antialiasing import with_supersample
from guaca_py.passes.debug_views import heat_color, legend_rows
from guaca_py.passes.light_grid_cpu import compare_grids, exact_tile_lights
from guaca_py.scene.graph import Camera, Light, MaterialInstance, Node, Scene, Transform
from guaca_py.scene.loader import load_scene

ROOT = Path(__file__).resolve().parents[2]


def pipeline(mode: str, tile: int = 16, extra: str = "", max_lights: int = 1024, tile_bits: str = "auto"):
    """A linear-output pipeline (no tone mapping) with the given culling mode."""
    return pipeline_from_text(f"""
transparency: {{method: presort_lf_et, threshold: 0.999}}
passes:
  - geometry: {{}}
  - light_culling: {{mode: {mode}, tile_size: {tile}, max_lights: {max_lights}, tile_bits: {tile_bits}}}
  - composite: {{}}
{extra}""")


def random_lights(rng, n: int, cam: Camera) -> list[Light]:
    """Point and spot lights of every awkward kind: around/containing the eye, behind it, off-screen, tiny."""
    eye = np.asarray(cam.position, dtype=np.float64)
    back = eye - np.asarray(cam.target, dtype=np.float64)
    back /= np.linalg.norm(back)
    out = []
    for i in range(n):
        kind = i % 5
        if kind == 0:  # around the camera, often containing it
            pos, rad = eye + rng.normal(size=3) * 0.6, rng.uniform(0.05, 2.0)
        elif kind == 1:  # behind the camera
            pos, rad = eye + back * rng.uniform(0.2, 4.0) + rng.normal(size=3), rng.uniform(0.2, 5.0)
        elif kind == 2:  # far to the side: partly off-screen
            pos = np.array([rng.choice([-1, 1]) * rng.uniform(3, 8), rng.uniform(-4, 4), rng.uniform(-6, 2)])
            rad = rng.uniform(1.0, 6.0)
        else:
            pos = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-15, 4)])
            rad = rng.uniform(0.1, 3.0) if rng.random() < 0.85 else rng.uniform(0.01, 0.1)
        d = rng.normal(size=3)
        out.append(
            Light(
                "spot" if i % 2 else "point",
                tuple(pos),
                tuple(d / np.linalg.norm(d)),
                (1, 1, 1),
                1.0,
                float(rad),
                inner_angle_deg=1.0,
                outer_angle_deg=float(rng.uniform(2, 89)),
            )
        )
    return out


CASES = [  # (seed, width, height, tile)
    (0, 96, 96, 16),
    (1, 100, 72, 13),
    (2, 64, 80, 8),
]


def _grid_vs_exact(renderer_factory, mode: str, seed: int, w: int, h: int, tile: int) -> dict:
    rng = np.random.default_rng(seed)
    scene = simple_scene([quad_node("q", 0.0, (1, 1, 1), 1.0, size=3.0)])
    scene.camera = Camera(
        position=tuple(rng.uniform(-1, 1, 3) + [0, 0, 5]),
        target=tuple(rng.uniform(-0.5, 0.5, 3)),
        fov_y=float(rng.uniform(40, 90)),
        near=0.1,
        far=60.0,
    )
    scene.lights = random_lights(rng, 140, scene.camera)
    r = renderer_factory(pipeline(mode, tile))
    frame = r.render(scene, w, h)
    lc = r.pass_named("light_culling")
    cam = scene.camera
    view, proj = cam.view_matrix(), cam.projection_matrix(w / h)
    packed = lc.packed_lights
    eye = np.asarray(cam.position)
    contains_eye = sum(np.linalg.norm(np.asarray(l.position) - eye) < l.radius for l in packed)
    assert len(packed) > 64 and contains_eye >= 3 and frame.stats["lights"]["rasterized"] == len(packed)
    exact = exact_tile_lights(packed, view, proj, w, h, tile)
    result = compare_grids(exact, lc.grid_bits())
    # lights the CPU frustum test dropped must not touch any tile
    culled = [l for l in scene.lights if not any(l is p for p in packed)]
    assert not exact_tile_lights(culled, view, proj, w, h, tile).any()
    result["visible"] = len(packed)
    return result


@pytest.mark.parametrize("seed,w,h,tile", CASES)
def test_fallback_grid_covers_every_exact_overlap(renderer_factory, seed, w, h, tile):
    c = _grid_vs_exact(renderer_factory, "fallback", seed, w, h, tile)
    print(
        f"fallback {w}x{h} tile {tile}: {c['visible']} lights, exact pairs {c['exact_pairs']}, "
        f"extra {c['extra']} ({100 * c['extra'] / c['exact_pairs']:.1f}%), missing {c['missing']}"
    )
    assert c["missing"] == 0, c
    assert c["extra"] <= 0.08 * c["exact_pairs"]  # proxies are ~4% larger than the volumes


@pytest.mark.parametrize("seed,w,h,tile", CASES[:2])
def test_conservative_grid_covers_every_exact_overlap(renderer_factory, gl_context, seed, w, h, tile):
    from guaca_py.context import detect_capabilities

    if not detect_capabilities(gl_context).conservative_raster:
        pytest.skip("device has no GL_NV_conservative_raster (llvmpipe): the fallback is tested instead")
    c = _grid_vs_exact(renderer_factory, "conservative", seed, w, h, tile)
    print(
        f"conservative {w}x{h} tile {tile}: exact pairs {c['exact_pairs']}, extra {c['extra']}, missing {c['missing']}"
    )
    assert c["missing"] == 0, c


def test_plain_rasterization_would_miss_tiles(renderer_factory):
    # The comparison is able to fail: proxies rasterized at tile centres only (no conservative
    # raster, no fallback) miss tiles that volumes overlap partly.
    class NoOp:
        def enable(self, cap):
            pass

        def disable(self, cap):
            pass

    rng = np.random.default_rng(5)
    scene = simple_scene([quad_node("q", 0.0, (1, 1, 1), 1.0)])
    scene.lights = random_lights(rng, 120, scene.camera)
    r = renderer_factory(pipeline("fallback"))
    lc = r.pass_named("light_culling")
    lc.mode, lc._raw_gl = "conservative", NoOp()  # the non-dilating program with ordinary rasterization
    r.render(scene, 96, 96)
    exact = exact_tile_lights(
        lc.packed_lights, scene.camera.view_matrix(), scene.camera.projection_matrix(1.0), 96, 96, 16
    )
    assert compare_grids(exact, lc.grid_bits())["missing"] > 10


def test_grid_check_in_stats_and_every_tile_lights(renderer_factory):
    cam = Camera(position=(0, 0, 5), target=(0, 0, 0), fov_y=50, near=0.1, far=30)
    lights = [
        Light("directional", direction=(0, -1, -1)),
        Light("point", (0, 0, 5), radius=40.0),  # spans near and far planes: every tile
        Light("point", (1, 1, 0), radius=0.5),
    ]
    scene = Scene(camera=cam, nodes=[quad_node("q", 0, (1, 1, 1), 1.0)], lights=lights)
    frame = renderer_factory(pipeline("fallback", extra="")).render(scene, 64, 64)
    s = frame.stats["lights"]
    assert s["every_tile"] == 2 and s["rasterized"] == 1 and s["mode"] == "fallback"
    r = renderer_factory(
        pipeline_from_text("passes: [geometry, {light_culling: {mode: fallback, report_accuracy: true}}, composite]")
    )
    s = r.render(scene, 64, 64).stats["lights"]
    assert s["grid_check"]["missing"] == 0 and s["grid_check"]["exact_pairs"] > 0
    bits = r.pass_named("light_culling").grid_bits()
    order = r.pass_named("light_culling").packed_lights
    for i, light in enumerate(order):
        if light.type == "directional" or light.radius == 40.0:
            assert bits[i].all()


# ----------------------------------------------------------------------------- images: culling on vs off
def lit_scene(n_lights: int = 120, seed: int = 3) -> Scene:
    """Opaque pbr wall and boxes, transparent pbr panes, n point/spot/directional lights."""
    rng = np.random.default_rng(seed)
    nodes = [
        Node(
            "wall",
            Transform((0, 0, -1.5)),
            unit_quad(8, 8),
            MaterialInstance("pbr", {"albedo": [0.7, 0.7, 0.7], "roughness": 0.6}),
        )
    ]
    for k in range(4):
        nodes.append(
            Node(
                f"pane{k}",
                Transform(
                    (rng.uniform(-1, 1), rng.uniform(-1, 1), -0.8 + 0.5 * k),
                    (rng.uniform(-30, 30), rng.uniform(-40, 40), 0),
                ),
                unit_quad(1.8, 1.8),
                MaterialInstance(
                    "pbr",
                    {
                        "albedo": list(rng.uniform(0.2, 1, 3)),
                        "roughness": 0.3,
                        "metalness": float(k == 2),
                        "alpha": 0.45,
                    },
                ),
            )
        )
    lights = [Light("directional", direction=(-0.2, -0.3, -1.0), color=(0.3, 0.3, 0.35), intensity=0.4)]
    for i in range(n_lights - 1):
        pos = (rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-1.2, 2.0))
        d = rng.normal(size=3)
        d[2] = -abs(d[2]) - 0.5
        lights.append(
            Light(
                "spot" if i % 3 == 0 else "point",
                pos,
                tuple(d / np.linalg.norm(d)),
                tuple(rng.uniform(0.2, 1, 3)),
                float(rng.uniform(0.3, 1.0)),
                float(rng.uniform(0.8, 2.0)),
                inner_angle_deg=10.0,
                outer_angle_deg=float(rng.uniform(20, 60)),
            )
        )
    return Scene(
        camera=Camera(position=(0, 0, 5), target=(0, 0, 0), fov_y=50, near=0.1, far=50),
        background=(0.02, 0.02, 0.03),
        nodes=nodes,
        lights=lights,
    )


@pytest.fixture(scope="module")
def culling_off_image(renderer_factory):
    return renderer_factory(pipeline("off")).render(lit_scene(), 96, 96)


@pytest.mark.parametrize("mode,tile_bits", [("fallback", "cache"), ("fallback", "fetch"), ("conservative", "auto")])
def test_images_agree_with_culling_off(renderer_factory, gl_context, culling_off_image, mode, tile_bits):
    from guaca_py.context import detect_capabilities

    if mode == "conservative" and not detect_capabilities(gl_context).conservative_raster:
        pytest.skip("device has no GL_NV_conservative_raster (llvmpipe)")
    off = culling_off_image
    on = renderer_factory(pipeline(mode, tile=16, tile_bits=tile_bits)).render(lit_scene(), 96, 96)
    assert on.stats["lights"]["visible"] >= 100 and on.stats["lights"]["mode"] == mode
    assert on.stats["fragments"]["stored"] > 0
    lin = np.abs(np.clip(on.linear, 0, 1) - np.clip(off.linear, 0, 1))
    img = np.abs(on.image.astype(int) - off.image.astype(int))
    print(
        f"{mode} vs off: max linear diff {lin.max() * 255:.4f}/255, max 8-bit diff {img.max()}, "
        f"mean {off.linear.mean():.3f}, clipped {(off.linear > 1).mean():.3f}"
    )
    assert lin.max() <= 1.0 / 255 and img.max() <= 1
    assert 0.05 < off.linear.mean() < 0.9  # lit, not black or blown out


def test_tile_bits_auto_follows_the_layer_count(renderer_factory):
    from guaca_py.passes.light_culling import CACHE_TILE_BITS_ABOVE

    lc = renderer_factory(pipeline("fallback")).pass_named("light_culling")
    lc.layers_allocated = CACHE_TILE_BITS_ABOVE
    assert lc.template_vars()["tile_bits_cached"] is False
    lc.layers_allocated = CACHE_TILE_BITS_ABOVE + 1
    assert lc.template_vars()["tile_bits_cached"] is True
    forced = renderer_factory(pipeline("fallback", tile_bits="fetch")).pass_named("light_culling")
    forced.layers_allocated = 4 * CACHE_TILE_BITS_ABOVE
    assert forced.template_vars()["tile_bits_cached"] is False


def test_grid_actually_culls(renderer_factory):
    r = renderer_factory(pipeline("fallback", tile=16))
    frame = r.render(lit_scene(), 96, 96)
    per_tile = r.pass_named("light_culling").grid_bits().sum(axis=0)
    assert per_tile.mean() < 0.5 * frame.stats["lights"]["visible"]


def test_layers_grow_only_when_needed(renderer_factory):
    r = renderer_factory(pipeline("fallback"))
    lc = r.pass_named("light_culling")
    scene = lit_scene(n_lights=10)
    r.render(scene, 48, 48)
    assert lc.layers_allocated == 1 and lc.template_vars() == {
        "light_grid": True,
        "max_light_layers": 1,
        "tile_bits_cached": False,
    }
    s = r.render(lit_scene(n_lights=70), 48, 48).stats["lights"]
    assert (s["layers"], s["layers_allocated"]) == (math.ceil(s["shaded"] / 32), 4)
    r.render(scene, 48, 48)
    assert lc.layers_allocated == 4  # kept, not shrunk
    r.render(scene, 80, 48)  # a new grid size starts small again
    assert lc.layers_allocated == 1


def test_max_lights_drops_are_reported(renderer_factory):
    frame = renderer_factory(pipeline("fallback", max_lights=40)).render(lit_scene(), 48, 48)
    s = frame.stats["lights"]
    assert s["shaded"] == 40 and s["dropped_over_max"] == s["visible"] - 40 > 0
    assert any("max_lights=40" in w for w in frame.stats["warnings"])


# ----------------------------------------------------------------------------- configuration
def test_mode_auto_is_default_and_resolves(renderer_factory, gl_context):
    from guaca_py.context import detect_capabilities
    from guaca_py.pipeline.config import load_pipeline

    assert load_pipeline("default").pass_settings("light_culling")["mode"] == "auto"
    assert load_pipeline("exact").pass_settings("light_culling")["mode"] == "off"
    assert pipeline_from_text("passes: [geometry, light_culling, composite]").pass_settings("light_culling") == {
        "mode": "auto",
        "tile_size": 16,
        "max_lights": 1024,
        "tile_bits": "auto",
        "report_accuracy": False,
    }
    lc = renderer_factory("default").pass_named("light_culling")
    has = detect_capabilities(gl_context).conservative_raster
    assert lc.mode == ("conservative" if has else "fallback")
    if not has:
        assert "GL_NV_conservative_raster" in lc.mode_note


def test_explicit_conservative_without_extension_is_a_clear_error(renderer_factory, gl_context):
    from guaca_py.context import detect_capabilities

    if detect_capabilities(gl_context).conservative_raster:
        pytest.skip("this device has GL_NV_conservative_raster")
    with pytest.raises(DeviceError, match="GL_NV_conservative_raster"):
        renderer_factory(pipeline("conservative"))


def test_bad_settings_are_config_errors():
    with pytest.raises(ConfigError, match="mode"):
        pipeline_from_text("passes: [geometry, {light_culling: {mode: tiled}}, composite]")
    with pytest.raises(ConfigError, match="tile_size"):
        pipeline_from_text("passes: [geometry, {light_culling: {tile_size: 0}}, composite]")


def test_raw_gl_calls_reach_the_context(gl_context):
    from guaca_py.gl_state import raw_gl

    gl = raw_gl()
    assert gl is not None
    GL_BLEND = 0x0BE2
    gl_context.disable(gl_context.BLEND)
    assert gl.try_enable(GL_BLEND) and gl.is_enabled(GL_BLEND)
    gl.disable(GL_BLEND)
    assert not gl.is_enabled(GL_BLEND)


# ----------------------------------------------------------------------------- 1,000 lights
def test_many_lights_scene_renders(renderer_factory):
    scene = load_scene(ROOT / "benchmarks" / "scenes" / "many_lights.yaml")
    assert len(scene.lights) == 1000
    frame = renderer_factory("default").render(scene, 128, 128)
    s = frame.stats
    assert s["lights"]["visible"] > 800 and s["lights"]["dropped_over_max"] == 0
    assert s["fragments"]["stored"] > 0 and s["fragments"]["overflow"] == 0
    assert s["lights"]["mode"] in ("conservative", "fallback")
    assert 20 < frame.image.mean() < 230


# ----------------------------------------------------------------------------- debug views
def test_debug_light_count_matches_grid(renderer_factory):
    r = renderer_factory(pipeline("fallback", tile=8, extra="  - debug_light_count: {max: 24, legend: false}\n"))
    frame = r.render(lit_scene(), 64, 64)
    counts = r.pass_named("light_culling").grid_bits().sum(axis=0)  # (tiles down, across), row 0 bottom
    img = frame.image[::-1].astype(float) / 255.0  # row 0 bottom like the grid
    want = np.array([[heat_color(c, 24) for c in row] for row in counts])
    got = img[4::8, 4::8]  # one pixel per tile
    assert np.abs(got - want).max() <= 1.0 / 255 + 1e-6
    assert frame.stats["debug_views"]["debug_light_count"]["tile_max"] == counts.max()
    assert len(np.unique(counts)) > 3


def test_debug_views_at_the_output_size_when_supersampled(renderer_factory):
    """antialiasing.supersample 2: each view is drawn at the output size (legend included) from the rendered frame:
    an output pixel shows the tile of its first rendered pixel, and the most fragments of its rendered pixels."""
    lights = with_supersample(
        pipeline("fallback", tile=8, extra="  - debug_light_count: {max: 24, legend: false}\n"), 2
    )
    r = renderer_factory(lights)
    frame = r.render(lit_scene(), 32, 32)
    counts = r.pass_named("light_culling").grid_bits().sum(axis=0)  # tiles of the 64x64 rendered frame
    want = np.array([[heat_color(c, 24) for c in row] for row in counts])
    got = frame.image[::-1].astype(float)[2::4, 2::4] / 255.0  # a tile is 4 output pixels wide
    assert frame.image.shape == (32, 32, 3) and np.abs(got - want).max() <= 1.0 / 255 + 1e-6
    complexity = with_supersample(pipeline("fallback", extra="  - debug_depth_complexity: {max: 8}\n"), 2)
    frame = renderer_factory(complexity).render(_complexity_scene(), 48, 48)
    img = frame.image.astype(float) / 255
    assert frame.image.shape == (48, 48, 3)
    assert np.abs(img[22:26, 22:26] - heat_color(5, 8)).max() <= 1.0 / 255 + 1e-6
    assert np.abs(img[1, 1] - heat_color(0, 8)).max() <= 1.0 / 255 + 1e-6
    assert (frame.image[48 - legend_rows(48) :] == 255).all(axis=-1).sum() > 10  # the legend's ticks and digits
    assert frame.stats["debug_views"]["debug_depth_complexity"]["pixel_max"] == 5


def test_debug_light_count_with_culling_off(renderer_factory):
    r = renderer_factory(pipeline("off", extra="  - debug_light_count: {max: 200, legend: false}\n"))
    frame = r.render(lit_scene(), 32, 32)
    n = frame.stats["lights"]["visible"]
    assert np.abs(frame.image.astype(float) / 255 - heat_color(n, 200)).max() <= 1.0 / 255 + 1e-6


def _complexity_scene():
    # 5 overlapping panes in the centre, 2 around it, none in the corners
    nodes = [quad_node(f"big{i}", -0.2 * i, (1, 0, 0), 0.3, size=2.4) for i in range(2)]
    nodes += [quad_node(f"small{i}", 0.5 - 0.2 * i, (0, 1, 0), 0.3, size=0.8) for i in range(3)]
    return simple_scene(nodes)


def test_debug_depth_complexity_counts_layers_with_legend(renderer_factory):
    r = renderer_factory(pipeline("fallback", extra="  - debug_depth_complexity: {max: 8}\n"))
    frame = r.render(_complexity_scene(), 96, 96)
    img = frame.image.astype(float) / 255
    assert np.abs(img[44:52, 44:52] - heat_color(5, 8)).max() <= 1.0 / 255 + 1e-6
    assert np.abs(img[30, 30] - heat_color(2, 8)).max() <= 1.0 / 255 + 1e-6
    assert np.abs(img[2, 2] - heat_color(0, 8)).max() <= 1.0 / 255 + 1e-6
    legend = frame.image[96 - legend_rows(96) :]
    assert (legend == 255).all(axis=-1).sum() > 20  # white tick marks and digits
    bar = legend.reshape(-1, 3)
    assert any(np.abs(bar.astype(float) / 255 - heat_color(8, 8)).max(axis=1) <= 1.5 / 255)  # top of the bar
    info = frame.stats["debug_views"]["debug_depth_complexity"]
    assert info["supported"] and info["pixel_max"] == 5  # the five panes of the centre
    frame = r.render(simple_scene(_complexity_scene().nodes[:2]), 64, 64)  # a second size, two panes
    assert frame.stats["debug_views"]["debug_depth_complexity"]["pixel_max"] == 2


@pytest.mark.parametrize("method", ["presort_lf", "presort_cs", "presort_lf_merge2_et", "post_sort", "post_merge16"])
def test_debug_depth_complexity_other_list_methods(renderer_factory, method):
    from guaca_py import UnsupportedMethodError

    try:
        r = renderer_factory(
            pipeline("off", extra="  - debug_depth_complexity: {max: 8, legend: false}\n"), method=method
        )
    except UnsupportedMethodError as exc:
        pytest.skip(str(exc))
    img = r.render(_complexity_scene(), 64, 64).image.astype(float) / 255
    assert np.abs(img[28:36, 28:36] - heat_color(5, 8)).max() <= 1.0 / 255 + 1e-6
    assert np.abs(img[20, 20] - heat_color(2, 8)).max() <= 1.0 / 255 + 1e-6


def test_debug_depth_complexity_unsupported_method_says_why(renderer_factory):
    r = renderer_factory(pipeline("fallback", extra="  - debug_depth_complexity: {max: 8}\n"), method="unsorted_blend")
    frame = r.render(simple_scene([quad_node("q", 0, (1, 0, 0), 0.5)]), 32, 32)
    info = frame.stats["debug_views"]["debug_depth_complexity"]
    assert not info["supported"] and "unsorted_blend" in info["reason"]
    assert any("debug_depth_complexity unsupported" in w for w in frame.stats["warnings"])


# ----------------------------------------------------------------------------- benchmark script
def test_benchmark_script_runs_tiny(tmp_path):
    out = tmp_path / "bench"
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "light_culling.py"),
            "--out",
            str(out),
            "--size",
            "64",
            "--lights",
            "1",
            "8",
            "--frames",
            "1",
            "--warmup",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))},
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads((out / "light_culling.json").read_text())
    assert [r["lights"] for r in data["results"]] == [1, 8]
    assert all(r["on"]["composite_ms"] > 0 and r["off"]["composite_ms"] > 0 for r in data["results"])
    assert (out / "light_culling.png").stat().st_size > 1000
    assert "off/on" in proc.stdout


@pytest.mark.parametrize("n_lights", [3, 90])  # kept while unchanged (few lights), gathered every frame (many)
def test_a_renderer_follows_light_edits_between_frames(renderer_factory, n_lights):
    # the light table is kept while the lights' values stay the same and an unchanged upload is not
    # sent again: a light moved, recoloured or retyped in place must show in the next frame exactly
    # as a fresh renderer draws it
    scene = lit_scene(n_lights=n_lights)
    used = renderer_factory(pipeline("fallback"))
    before = used.render(scene, 64, 64).image
    assert (used.render(scene, 64, 64).image == before).all()
    light = scene.lights[0]
    light.position = tuple(np.add(light.position, (0.4, -0.3, 0.2)))
    light.color = (1.0, 0.2, 0.1)
    light.intensity *= 3.0
    light.type = "spot" if light.type != "spot" else "point"
    after = used.render(scene, 64, 64).image
    fresh = renderer_factory(pipeline("fallback")).render(scene, 64, 64).image
    assert (after == fresh).all()
    assert (after != before).any()
