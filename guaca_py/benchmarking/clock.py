"""Sample the GPU's SM clock while a benchmark runs (NVIDIA only; silently absent elsewhere).

GPU timer queries measure time, and the time of a pass scales with the clock the driver picks:
on the H100 it ran the same frame at 1980 MHz and, after other work, at under 1000 MHz for
seconds at a time. Recording the clock beside the timings says which regime a table was taken in,
and a point whose median clock was under a share of the maximum (90% unless a benchmark asks for
more) is measured again (up to RETRIES).
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
import threading
from collections.abc import Callable
from functools import lru_cache
from typing import TypeVar

T = TypeVar("T")

RETRIES = 2  # extra attempts a benchmark point gets when its clock was throttled


@lru_cache(maxsize=1)
def max_sm_clock() -> int | None:
    """The GPU's maximum SM clock in MHz (nvidia-smi clocks.max.sm), or None."""
    exe = shutil.which("nvidia-smi")
    if not exe:
        return None
    try:
        out = subprocess.run(
            [exe, "--query-gpu=clocks.max.sm", "--format=csv,noheader,nounits"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout
        return int(out.split()[0])
    except (ValueError, IndexError, subprocess.SubprocessError):
        return None


class ClockSampler:
    """Context manager: polls `nvidia-smi` for clocks.sm every `period_ms`; summary() afterwards."""

    def __init__(self, period_ms: int = 100) -> None:
        self.period_ms = period_ms
        self.samples: list[int] = []
        self._proc = None
        self._thread = None

    def __enter__(self) -> ClockSampler:
        exe = shutil.which("nvidia-smi")
        if exe:
            self._proc = subprocess.Popen(
                [exe, "--query-gpu=clocks.sm", "--format=csv,noheader,nounits", f"-lms={self.period_ms}"],
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                text=True,
            )
            self._thread = threading.Thread(target=self._read, daemon=True)
            self._thread.start()
        return self

    def _read(self) -> None:
        for line in self._proc.stdout:
            try:
                self.samples.append(int(line.split(",")[0]))
            except ValueError:
                pass

    def __exit__(self, *exc) -> None:
        if self._proc is not None:
            self._proc.terminate()
            self._proc.wait(timeout=5)
            self._thread.join(timeout=5)

    def restart(self) -> None:
        """Drop the samples so far (a warm-up's): summary() and throttled() describe what follows."""
        self.samples.clear()

    def throttled(self, share: float = 0.9) -> bool:
        """True when the median sampled clock was under `share` of the device's maximum."""
        top = max_sm_clock()
        return bool(self.samples and top and statistics.median(self.samples) < share * top)

    def summary(self) -> dict | None:
        """Median, min and max SM clock in MHz over the samples, or None without nvidia-smi."""
        return clock_summary(self.samples)


def clock_summary(samples: list[int]) -> dict | None:
    """Median, min and max of SM clock samples in MHz, or None when there are none."""
    if not samples:
        return None
    return {
        "sm_clock_mhz_median": statistics.median(samples),
        "sm_clock_mhz_min": min(samples),
        "sm_clock_mhz_max": max(samples),
        "sm_clock_samples": len(samples),
    }


def at_full_clock(
    measure: Callable[[], T],
    valid: Callable[[T], bool] = lambda _: True,
    warm_up: Callable[[], object] | None = None,
    share: float = 0.9,
    period_ms: int = 100,
) -> tuple[T, ClockSampler, int]:
    """Run `measure` under a ClockSampler, again (up to RETRIES) while the clock was under `share` of its maximum.

    `warm_up`, where given, runs first in every attempt with the sampler already polling; its samples
    are dropped, so the point's clock is that of `measure` alone, and nvidia-smi's start-up (a few
    hundred ms without a sample) falls in the warm-up. Returns the last result, its sampler and the
    number of retries; an invalid result (a failed run) is not retried.
    """
    for attempt in range(RETRIES + 1):  # noqa: B007 - returned after the loop
        with ClockSampler(period_ms) as clock:
            if warm_up is not None:
                warm_up()
                clock.restart()
            result = measure()
        if not valid(result) or not clock.throttled(share):
            break
    return result, clock, attempt


def below_max_clock(clock: dict | None, top: float | None) -> bool:
    """Whether a row is not known to have run at the maximum SM clock: its median was below `top`, or
    nothing was sampled on a device that has a maximum. Without a maximum (no nvidia-smi) never."""
    return top is not None and (clock is None or clock["sm_clock_mhz_median"] < top)


def top_clock(record: dict) -> float | None:
    """The maximum SM clock a record's rows are judged by: the one it stored ("max_sm_clock_mhz", None
    without nvidia-smi), else, for records made before it was stored, the highest clock a row sampled."""
    if "max_sm_clock_mhz" in record:
        return record["max_sm_clock_mhz"]
    seen = [r["clock"]["sm_clock_mhz_max"] for r in record["rows"] if r.get("clock")]
    return max(seen) if seen else None


def ratio_at_full_clock(base: dict, other: dict, top: float | None, key: str = "ms") -> float | None:
    """other[key] / base[key] where both rows ran at the maximum SM clock (or none is known), else None:
    times taken at different clocks are not compared."""
    if below_max_clock(base.get("clock"), top) or below_max_clock(other.get("clock"), top):
        return None
    return other[key] / base[key]
