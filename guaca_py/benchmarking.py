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
    return measure_interleaved({"": renderer}, scene, width, height, warmup, frames)[""]


def measure_interleaved(
    renderers: dict, scene, width: int, height: int, warmup: int = 5, frames: int = 10
) -> dict[str, Measurement]:
    """Like measure() for several renderers at once, one frame of each per round."""
    for _ in range(warmup):
        for r in renderers.values():
            r.render(scene, width, height)
    samples: dict[str, dict[str, list[float]]] = {k: {} for k in renderers}
    totals: dict[str, list[float]] = {k: [] for k in renderers}
    last: dict[str, FrameResult] = {}
    for _ in range(max(1, frames)):
        for key, r in renderers.items():
            res = last[key] = r.render(scene, width, height)
            for name, p in res.stats["passes"].items():
                samples[key].setdefault(name, []).append(p["ms"])
            totals[key].append(sum(p["ms"] for p in res.stats["passes"].values()))
    return {
        k: Measurement(
            {n: statistics.median(v) for n, v in samples[k].items()},
            statistics.median(totals[k]),
            len(totals[k]),
            last[k].stats.get("timer", "?"),
            last[k],
        )
        for k in renderers
    }
