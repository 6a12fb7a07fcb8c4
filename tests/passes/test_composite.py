"""The composite pass's launch order: strips of workgroups over large frames, the same image."""

from __future__ import annotations

import numpy as np
import pytest
from test_antialiasing import random_quads

from guaca_py.antialiasing import with_supersample
from guaca_py.passes import composite
from guaca_py.pipeline.config import load_pipeline
from guaca_py.raster.choice import LARGE_FRAME_PIXELS
from guaca_py.raster.compute_raster import ORDER_TILE_BITS


def test_strips_are_screen_tiles_wide_in_tile_order_frames_only():
    side = int(LARGE_FRAME_PIXELS**0.5)
    assert composite.composite_strip(side, side, 8) == 0  # depth order: row by row
    big = 2 * side
    tile = big >> ORDER_TILE_BITS
    assert composite.composite_strip(big, big, 8) == composite.STRIP_TILES * tile // 8
    wider = (big + 64) >> ORDER_TILE_BITS
    assert composite.composite_strip(big + 64, big, 8) == -(-(composite.STRIP_TILES * wider) // 8)


@pytest.mark.parametrize("supersample", [1, 2])
@pytest.mark.parametrize("strip", [1, 3, 4])
def test_launch_in_strips_composites_every_pixel_alike(renderer_factory, monkeypatch, supersample, strip):
    # 80 px wide: 10 workgroups of 8 (20 of 8 rendered pixels at supersample 2), so strips of 3 and 4
    # leave a narrower last strip; every pixel is composited once and exactly as row by row
    pipeline = load_pipeline("exact") if supersample == 1 else with_supersample(load_pipeline("exact"), supersample)
    scene = random_quads(3)
    rows = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    monkeypatch.setattr(composite, "composite_strip", lambda w, h, edge: strip)
    # a renderer of its own: a pixel the strips missed would otherwise keep the last frame's value
    strips = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    assert len(np.unique(rows.reshape(-1, 3), axis=0)) > 8  # quads over a background, not a flat frame
    np.testing.assert_array_equal(strips, rows)
