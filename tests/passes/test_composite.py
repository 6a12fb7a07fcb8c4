"""The composite pass's launch order: strips of workgroups over large frames, the same image."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import random_quads

from guaca_py.antialiasing import with_supersample
from guaca_py.passes import composite
from guaca_py.pipeline.config import load_pipeline


def test_strips_are_two_screen_tiles_wide_where_nodes_lie_by_tile_only():
    # 16 x 16 screen tiles (raster/compute_raster.py ORDER_TILE_BITS = 4): at 4096 px a tile is 256 px,
    # two are 512 px, 64 workgroups of 8 (32 of 16); at 3000 px two tiles are 2 x 187 px: 47 groups of 8
    by_tile = SimpleNamespace(nodes_by_tile=True)
    assert composite.composite_strip(by_tile, 4096, 8) == 64
    assert composite.composite_strip(by_tile, 4096, 16) == 32
    assert composite.composite_strip(by_tile, 3000, 8) == 47
    assert composite.composite_strip(SimpleNamespace(nodes_by_tile=False), 4096, 8) == 0  # drawn otherwise
    assert composite.composite_strip(None, 4096, 8) == 0  # nothing transparent


@pytest.mark.parametrize(
    "pixels,order,compute,expected",
    [
        (4096 * 4096, "tile", True, True),
        (2048 * 2048, "tile", True, False),  # not a large frame: the small frames' buckets
        (4096 * 4096, "depth", True, False),  # nodes in depth order
        (4096 * 4096, "tile", False, False),  # every draw through the hardware: nodes in its order
    ],
)
def test_the_router_says_whether_a_frame_s_nodes_lie_by_tile(monkeypatch, pixels, order, compute, expected):
    from guaca_py.raster.router import RasterRouter

    router = RasterRouter.__new__(RasterRouter)  # no device: choose() and the rasterizers are stood in for
    router._stats_of, router._drew_compute, router._compute = None, False, SimpleNamespace(draw=lambda *a: None)
    router.hardware = SimpleNamespace(draw=lambda *a, **k: None)
    monkeypatch.setattr(router, "choose", lambda frame, d: ("compute" if compute else "hardware", "test"))
    method = SimpleNamespace(settings={"raster": "auto"}, raster_order=lambda px: order)
    frame = SimpleNamespace(method=method, pixel_count=pixels, stats={})
    router.draw(frame, [object()], {})
    assert router.nodes_by_tile(frame) is expected
    assert router.nodes_by_tile(SimpleNamespace()) is False  # another frame: not this one's order


@pytest.mark.parametrize("supersample", [1, 2])
@pytest.mark.parametrize("strip", [1, 3, 4])
def test_launch_in_strips_composites_every_pixel_alike(renderer_factory, monkeypatch, supersample, strip):
    # 80 px wide: 10 workgroups of 8 (20 of 8 rendered pixels at supersample 2), so strips of 3 and 4
    # leave a narrower last strip; every pixel is composited once and exactly as row by row
    pipeline = load_pipeline("exact") if supersample == 1 else with_supersample(load_pipeline("exact"), supersample)
    scene = random_quads(3)
    rows = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    monkeypatch.setattr(composite, "composite_strip", lambda store, width, edge: strip)
    # a renderer of its own: a pixel the strips missed would otherwise keep the last frame's value
    strips = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    assert len(np.unique(rows.reshape(-1, 3), axis=0)) > 8  # quads over a background, not a flat frame
    np.testing.assert_array_equal(strips, rows)
