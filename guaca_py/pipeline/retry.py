"""The one retry policy: a frame (or the part of it a method draws) is drawn again while its storage grew."""

from __future__ import annotations

from collections.abc import Callable

# A safety bound on re-draws of one frame: each grower stops earlier by its own budget (a method's
# `max_regrow` setting, the compute rasterizer's queues), so this only ends a grower that never settles.
MAX_REDRAWS = 16


def settle(attempt: Callable[[], bool], stats) -> None:
    """Run `attempt` until it returns False (nothing grew), at most 1 + MAX_REDRAWS times.

    Each repeat is counted in stats['regrown'], the count every grower reads as "re-draws of
    this frame so far".
    """
    for _ in range(MAX_REDRAWS):
        if not attempt():
            return
        stats["regrown"] = stats.get("regrown", 0) + 1
    attempt()
