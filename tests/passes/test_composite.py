"""The composite pass's launch order: strips of workgroups over large frames, the same image."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import random_quads

from guaca_py.antialiasing import with_supersample
from guaca_py.passes import composite
from guaca_py.pipeline.config import load_pipeline


def frame_of(width: int, height: int, order: str) -> SimpleNamespace:
    """What composite_strip reads of a frame: its rendered size and its method's triangle order."""
    return SimpleNamespace(width=width, height=height, method=SimpleNamespace(raster_order=lambda pixels: order))


def test_strips_are_two_screen_tiles_wide_in_large_tile_order_frames_only():
    # 16 x 16 screen tiles (raster/compute_raster.py ORDER_TILE_BITS = 4): at 4096 px a tile is 256 px,
    # two are 512 px, 64 workgroups of 8 (32 of 16); at 3000 px two tiles are 2 x 187 px: 47 groups of 8
    assert composite.composite_strip(frame_of(4096, 4096, "tile"), 8) == 64
    assert composite.composite_strip(frame_of(4096, 4096, "tile"), 16) == 32
    assert composite.composite_strip(frame_of(3000, 3000, "tile"), 8) == 47
    assert composite.composite_strip(frame_of(2048, 2048, "tile"), 8) == 0  # not a large frame
    assert composite.composite_strip(frame_of(4096, 4096, "depth"), 8) == 0  # nodes not in tile order


@pytest.mark.parametrize("supersample", [1, 2])
@pytest.mark.parametrize("strip", [1, 3, 4])
def test_launch_in_strips_composites_every_pixel_alike(renderer_factory, monkeypatch, supersample, strip):
    # 80 px wide: 10 workgroups of 8 (20 of 8 rendered pixels at supersample 2), so strips of 3 and 4
    # leave a narrower last strip; every pixel is composited once and exactly as row by row
    pipeline = load_pipeline("exact") if supersample == 1 else with_supersample(load_pipeline("exact"), supersample)
    scene = random_quads(3)
    rows = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    monkeypatch.setattr(composite, "composite_strip", lambda frame, edge: strip)
    # a renderer of its own: a pixel the strips missed would otherwise keep the last frame's value
    strips = renderer_factory(pipeline, method="presort_lf_et").render(scene, 80, 56).linear
    assert len(np.unique(rows.reshape(-1, 3), axis=0)) > 8  # quads over a background, not a flat frame
    np.testing.assert_array_equal(strips, rows)
