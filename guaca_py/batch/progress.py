"""Progress of a batch job: frames done / total, frames per second and the time left.

With tqdm installed (`pip install "guaca_py[progress]"`) a progress bar; without it a line on
stderr every few seconds. Frames skipped by a rerun count as done but not in the rate.
"""

from __future__ import annotations

import sys
import time


class Progress:
    """Counts rendered frames against the job's total and reports them."""

    def __init__(self, total: int, skipped: int, show: bool = True, every_s: float = 5.0, clock=time.perf_counter):
        self.total, self.done, self.rendered = total, skipped, 0
        self.clock = clock  # seconds; a test hands in its own
        self.t0 = clock()
        self.show, self.every_s, self._last = show, every_s, self.t0
        self.bar = None
        if show:
            try:
                from tqdm import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self.bar = tqdm(total=total, initial=skipped, unit="frame", desc="batch", file=sys.stderr)

    @property
    def fps(self) -> float:
        """Frames rendered per second since the start."""
        spent = self.clock() - self.t0
        return self.rendered / spent if spent > 0 else 0.0

    def eta(self) -> float | None:
        """Seconds left at the rate so far (None before the first frame)."""
        return (self.total - self.done) / self.fps if self.rendered else None

    def line(self) -> str:
        """'frames 12/48, 3.1 frames/s, ETA 11 s'."""
        from ..benchmarking.harness import _duration  # worded as the benchmarks' progress lines

        eta = self.eta()
        return f"frames {self.done}/{self.total}, {self.fps:.2f} frames/s, ETA {'?' if eta is None else _duration(eta)}"

    def step(self) -> None:
        """One more frame written."""
        self.done += 1
        self.rendered += 1
        if self.bar is not None:
            self.bar.update(1)
        elif self.show and (self.clock() - self._last >= self.every_s or self.done == self.total):
            self._last = self.clock()
            print(self.line(), file=sys.stderr, flush=True)

    def close(self) -> None:
        """End the bar."""
        if self.bar is not None:
            self.bar.close()
