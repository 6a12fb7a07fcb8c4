"""How storage that grows to a measured need is sized: one margin over the need, one shrink rule.

Every buffer sized from last frame's counters that drops what does not fit (the A-buffer's node
pool, paged_ll's pages, the compute rasterizer's queues) grows to `with_margin(need)` when a
frame overflows it, and shrinks back to that size once `idles(capacity, need)`. (Multi-layer
peeling's node pool is not one of them: it never drops, a smaller pool costs it more passes, so it
shrinks only when three quarters of it idle: methods/peeling_multilayer.py.) The margin keeps a
scene whose need wobbles from frame to frame (a moving camera, races between fragments) from
growing every frame; the shrink threshold lies above it, so a steady scene never oscillates, and
below 1.2x, so a steady pool holds at most 1.2x what it stores (issue: "Memory: after a steady
frame, every pool holds at most 1.2x the bytes of the nodes it stored").
"""

from __future__ import annotations

#: a grown (or shrunk) buffer holds its need times this, plus `slack` entries
MARGIN = 1.10
#: a buffer shrinks once it holds more than its need times this (plus the slack)
SHRINK_ABOVE = 1.20


def with_margin(need: float, slack: int = 1024) -> int:
    """Entries to hold for a measured `need`: the need, its margin and `slack` (small needs get room too)."""
    return int(need * MARGIN) + slack


def idles(capacity: int, need: float, slack: int = 1024) -> bool:
    """Whether a buffer of `capacity` entries holds so much more than `need` that it should shrink to with_margin(need)."""
    return capacity > int(need * SHRINK_ABOVE) + slack
