"""Measure frames the way the performance protocol asks: warm-up, then medians of per-pass times.

Times are what a frame's stats report: GPU timer queries on a GPU (stats["timer"] == "gpu"), the
wall clock around each pass on a software rasterizer ("wall"), which is no GPU time and is labelled
as such wherever a benchmark writes it.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from .. import FrameResult, Renderer
from ..scene.graph import Scene
from .clock import at_full_clock


@dataclass
class Measurement:
    """Median per-pass times over measured frames, plus the last frame (image and counters)."""

    pass_ms: dict[str, float]
    total_ms: float
    frames: int
    timer: str
    last: FrameResult


def measure(
    renderer: Renderer, scene: Scene, width: int, height: int, warmup: int = 3, frames: int = 10
) -> Measurement:
    """Render `warmup` frames untimed, then `frames` timed ones; per-pass medians in ms."""
    return measure_interleaved({"": renderer}, scene, width, height, warmup, frames)[""]


def measure_interleaved(
    renderers: dict[str, Renderer], scene: Scene, width: int, height: int, warmup: int = 5, frames: int = 10
) -> dict[str, Measurement]:
    """Like measure() for several renderers at once, one frame of each per round (clock drift hits all alike)."""
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


def warm_up(renderer: Renderer, scene: Scene, width: int, height: int, frames: int = 2, seconds: float = 0.0) -> int:
    """Untimed frames without read-back, at least `frames` and for `seconds` (a GPU's clock ramps up only
    under load); the number rendered."""
    t_end = time.perf_counter() + seconds
    n = 0
    while n < frames or time.perf_counter() < t_end:
        renderer.render(scene, width, height, read_back=False)
        renderer.ctx.finish()
        n += 1
    return n


@dataclass
class Point:
    """One configuration's timing: per-pass medians held at the full SM clock where one is sampled."""

    pass_ms: dict[str, float]
    total_ms: float
    frames: int
    timer: str
    warmup_frames: int
    clock: dict | None  # median, min and max SM clock while timing (nvidia-smi), None without it
    clock_retries: int
    extra: dict = field(default_factory=dict)  # what `then` measured under the same clock sampler
    last: FrameResult | None = None

    def as_dict(self) -> dict:
        """The timing as JSON-ready values (no frame)."""
        return {
            "passes_ms": self.pass_ms,
            "total_ms": self.total_ms,
            "frames": self.frames,
            "timer": self.timer,
            "warmup_frames": self.warmup_frames,
            "clock": self.clock,
            "clock_retries": self.clock_retries,
            **self.extra,
        }


def measure_point(
    renderer: Renderer,
    scene: Scene,
    width: int,
    height: int | None = None,
    *,
    frames: int = 8,
    warmup: int = 2,
    warmup_s: float = 1.5,
    hold_s: float = 0.3,
    slow_s: float = 3.0,
    slow_frames: int = 1,
    share: float = 0.9,
    then: Callable[[], dict] | None = None,
) -> Point:
    """Time one configuration: a first frame (compiles programs, grows pools), a warm-up, `frames` timed frames.

    The warm-up renders at least `warmup` frames, and on a GPU for `warmup_s` seconds as well (the
    clock ramps up only under load; software rasterizers get no time-based warm-up). The timed
    frames are followed by untimed ones until `hold_s` has passed, so that the clock sampler (every
    100 ms) sees this configuration run; warm-up and timing are repeated (clock.RETRIES times at
    most) while the sampled SM clock was under `share` of its maximum. A first frame slower than
    `slow_s`: `slow_frames` timed frames, no warm-up. `then`, where given, runs after the timed
    frames under the same sampler (a frame loop, say) and its dict lands in Point.extra.
    """
    height = width if height is None else height
    t0 = time.perf_counter()
    first = renderer.render(scene, width, height)
    slow = time.perf_counter() - t0 > slow_s
    gpu = first.stats.get("timer") == "gpu"
    n_timed = min(frames, slow_frames) if slow else frames
    n_warm = [0]

    def warm() -> None:
        n_warm[0] = warm_up(renderer, scene, width, height, max(0, warmup - 1), warmup_s if gpu else 0.0)

    def timed() -> tuple[dict, list, FrameResult, dict]:
        t_start = time.perf_counter()
        passes: dict[str, list[float]] = {}
        totals = []
        last = first
        for _ in range(max(1, n_timed)):
            last = renderer.render(scene, width, height)
            for name, p in last.stats["passes"].items():
                passes.setdefault(name, []).append(p["ms"])
            totals.append(sum(p["ms"] for p in last.stats["passes"].values()))
        extra = then() if then is not None else {}
        while gpu and not slow and time.perf_counter() - t_start < hold_s:
            renderer.render(scene, width, height, read_back=False)
            renderer.ctx.finish()
        return passes, totals, last, extra

    (passes, totals, last, extra), clock, retries = at_full_clock(timed, warm_up=None if slow else warm, share=share)
    return Point(
        {k: statistics.median(v) for k, v in passes.items()},
        statistics.median(totals),
        len(totals),
        last.stats.get("timer", "?"),
        n_warm[0] + 1,
        clock.summary(),
        retries,
        extra,
        last,
    )
