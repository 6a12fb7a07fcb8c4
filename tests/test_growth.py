"""The one sizing rule of storage that grows to a measured need (guaca_py/growth.py)."""

from __future__ import annotations

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


def test_the_margin_lies_below_the_shrink_line():
    assert 1.0 < MARGIN < SHRINK_ABOVE <= 1.2
