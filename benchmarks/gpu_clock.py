"""Sample the GPU's SM clock while a benchmark runs (NVIDIA only; silently absent elsewhere).

GPU timer queries measure time, and the time of a pass scales with the clock the driver picks:
on the H100 it ran the same frame at 1980 MHz and, after other work, at under 1000 MHz for
seconds at a time. Recording the clock beside the timings says which regime a table was taken in.
"""
from __future__ import annotations

import shutil
import statistics
import subprocess
import threading


class ClockSampler:
    """Context manager: polls `nvidia-smi` for clocks.sm every `period_ms`; summary() afterwards."""

    def __init__(self, period_ms: int = 100):
        self.period_ms = period_ms
        self.samples: list[int] = []
        self._proc = None
        self._thread = None

    def __enter__(self) -> "ClockSampler":
        exe = shutil.which("nvidia-smi")
        if exe:
            self._proc = subprocess.Popen([exe, "--query-gpu=clocks.sm", "--format=csv,noheader,nounits",
                                           f"-lms={self.period_ms}"], stdout=subprocess.PIPE,
                                          stderr=subprocess.DEVNULL, text=True)
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

    def summary(self) -> dict | None:
        """Median, min and max SM clock in MHz over the samples, or None without nvidia-smi."""
        if not self.samples:
            return None
        return {"sm_clock_mhz_median": statistics.median(self.samples), "sm_clock_mhz_min": min(self.samples),
                "sm_clock_mhz_max": max(self.samples), "sm_clock_samples": len(self.samples)}
