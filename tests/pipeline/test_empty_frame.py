"""Work a frame does not need is not done: empty frames build no light grid and skip FXAA; tone
mapping is fused into the composite where nothing else reads the HDR image."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from conftest import quad_node, simple_scene

from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.scene.graph import Camera, Scene
from guaca_py.scene.loader import demo_scene

DEFAULT_TEXT = load_pipeline("default").source


def _default_text(drop_fxaa: bool = False) -> str:
    with open(DEFAULT_TEXT) as f:
        text = f.read()
    return text.replace("  - fxaa: {}\n", "") if drop_fxaa else text


def _empty(lights) -> Scene:
    return Scene(
        nodes=[], camera=Camera(position=[0, 0, 1], target=[0, 0, 0]), lights=lights, background=[0.3, 0.2, 0.7]
    )


def test_empty_frame_dispatches_no_light_culling(renderer_factory):
    r = renderer_factory("default")
    lc = r.pass_named("light_culling")
    demo = demo_scene()
    r.render(demo, 64, 48)
    built = lc.grids_built
    assert built > 0  # a lit scene with surfaces builds its grid
    for lights, reason in (([], "no visible lights"), (copy.deepcopy(demo.lights), "nothing to shade (no draws)")):
        frame = r.render(_empty(lights), 64, 48)
        assert lc.grids_built == built, reason
        assert frame.stats["lights"]["grid_skipped"] == reason
        assert frame.stats["skipped"]["fxaa"]
        # one colour: the background through the tone curve, as before
        assert (frame.image == frame.image[0, 0]).all()
    # no lights at all, with surfaces: still no grid, and the composite reads none of the stale one
    dark = copy.deepcopy(demo)
    dark.lights = []
    frame = r.render(dark, 64, 48)
    assert lc.grids_built == built and frame.stats["lights"]["grid_skipped"] == "no visible lights"
    assert frame.image.std() > 1  # emissive, unlit and transparent surfaces still show
    unlit_ref = renderer_factory("default", fuse_passes=False)
    unlit_ref.render(demo, 64, 48)  # its grid holds the demo's bits when the dark frame comes
    assert np.array_equal(unlit_ref.render(dark, 64, 48).image, frame.image)
    r.render(demo, 64, 48)
    assert lc.grids_built == built + 1


def test_light_grid_is_built_when_a_debug_view_reads_it(renderer_factory):
    cfg = load_pipeline("default")
    text = _default_text().replace("  - fxaa: {}\n", "  - debug_light_count: {}\n")
    r = renderer_factory(pipeline_from_text(text, cfg.source))
    frame = r.render(_empty(copy.deepcopy(demo_scene().lights)), 64, 48)
    assert "grid_skipped" not in frame.stats["lights"]
    assert frame.stats["debug_views"]["debug_light_count"]["tile_max"] > 0


def test_tone_mapping_is_fused_only_when_nothing_reads_hdr(renderer_factory):
    fused = renderer_factory("default")
    assert fused.pass_named("tone_mapping").fused_into == "composite"
    s = fused.render(demo_scene(), 64, 48).stats["passes"]
    assert list(s) == ["geometry", "light_culling", "composite", "tone_mapping", "fxaa"]
    assert s["tone_mapping"] == {"ms": 0.0, "fused_into": "composite"} and s["composite"]["includes"] == "tone_mapping"
    assert renderer_factory("default", fuse_passes=False).pass_named("tone_mapping").fused_into is None
    assert renderer_factory("exact").pass_named("composite").epilogue is None  # no tone mapping to fuse


@pytest.mark.parametrize("drop_fxaa", [True, False])
def test_fused_and_unfused_pipelines_agree(renderer_factory, drop_fxaa):
    cfg = pipeline_from_text(_default_text(drop_fxaa))
    fused, unfused = renderer_factory(cfg), renderer_factory(cfg, fuse_passes=False)
    opaque = demo_scene()
    opaque.nodes = [n for n in opaque.nodes if n.name != "glass_cluster"]
    scenes = [demo_scene(), opaque, _empty([]), simple_scene([quad_node("q", 0.0, (0.9, 0.3, 0.1), 0.5)])]
    for scene in scenes:
        a = fused.render(scene, 96, 72).image.astype(int)
        b = unfused.render(scene, 96, 72).image.astype(int)
        d = np.abs(a - b)
        if drop_fxaa:
            # the unfused composite stores HDR in half floats; the fused one tone-maps the float value
            assert d.max() <= 1
        else:
            # FXAA's edge test is a threshold: a 1/255 change at its input may flip it at a few edges
            assert np.mean(d <= 1) > 0.97 and d.max() <= 16
