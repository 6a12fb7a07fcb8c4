"""The one sizing rule of storage that grows to a measured need (guaca_py/growth.py)."""

from __future__ import annotations

import numpy as np
import pytest

from guaca_py.growth import MARGIN, SHRINK_ABOVE, idles, with_margin


@pytest.mark.parametrize("need", [0, 1, 1000, 123_457, 40_000_000])
def test_a_grown_buffer_holds_its_need_and_does_not_shrink_at_once(need):
    size = with_margin(need)
    assert need < size <= need * MARGIN + 1024
    assert not idles(size, need)  # no oscillation: grown to a need, it stays while the need stays
    assert not idles(size, need * 0.95)  # nor when the need wobbles down a little


@pytest.mark.parametrize("need", [0, 5000, 2_000_000])
def test_a_buffer_above_the_shrink_line_shrinks_to_at_most_1_2x(need):
    above = int(need * SHRINK_ABOVE) + 1025
    assert idles(above, need)
    assert with_margin(need) <= need * SHRINK_ABOVE + 1024  # what it shrinks to is under the line
    assert not idles(int(need * SHRINK_ABOVE) + 1024, need)  # on the line: kept


def test_a_steady_scene_settles_within_1_2x_and_stays_there():
    """The rule as the A-buffer applies it, frame by frame: grow to with_margin(need) on overflow, shrink to it once
    idles(). A pool grown 4x by early termination's first guess, then a need that wobbles +-4 % around 2M nodes:
    one shrink, no overflow, no further resize, and never more than 1.2x the need (+ the slack) after it."""
    rng = np.random.default_rng(3)
    needs = 2_000_000 * (1 + 0.04 * rng.uniform(-1, 1, 200))
    capacity, resizes, overflows = 8_000_000, 0, 0
    for frame, need in enumerate(needs):
        if need > capacity:
            overflows += 1
            capacity, resizes = with_margin(need), resizes + 1
        elif idles(capacity, need):
            capacity, resizes = with_margin(need), resizes + 1
        if frame:
            assert capacity <= SHRINK_ABOVE * need + 1024, (frame, capacity, need)
    assert (resizes, overflows) == (1, 0)
