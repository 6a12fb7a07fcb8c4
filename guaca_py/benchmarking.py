"""Measure frames the way the performance protocol asks: warm-up, then medians of per-pass times."""
from __future__ import annotations

import statistics
from dataclasses import dataclass

from .pipeline.frame import FrameResult


@dataclass
class Measurement:
    """Median per-pass times over measured frames, plus the last frame (image and counters)."""

    pass_ms: dict[str, float]
    total_ms: float
    frames: int
    timer: str
    last: FrameResult


def measure(renderer, scene, width: int, height: int, warmup: int = 3, frames: int = 10) -> Measurement:
    """Render `warmup` frames untimed, then `frames` timed ones; per-pass medians in ms."""
    for _ in range(warmup):
        renderer.render(scene, width, height)
    samples: dict[str, list[float]] = {}
    totals = []
    last = None
    for _ in range(max(1, frames)):
        last = renderer.render(scene, width, height)
        for name, p in last.stats["passes"].items():
            samples.setdefault(name, []).append(p["ms"])
        totals.append(sum(p["ms"] for p in last.stats["passes"].values()))
    return Measurement({k: statistics.median(v) for k, v in samples.items()}, statistics.median(totals),
                       len(totals), last.stats.get("timer", "?"), last)
