"""The anti-aliasing benchmark's clock rules: rows below the maximum SM clock are marked, and never compared."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import accuracy_scenes  # noqa: E402
import gpu_clock  # noqa: E402


def clock(mhz: float) -> dict:
    return {"sm_clock_mhz_median": mhz, "sm_clock_mhz_min": mhz, "sm_clock_mhz_max": mhz, "sm_clock_samples": 3}


def row(label: str, samples: int, ms: float, mhz: float | None) -> dict:
    return {
        "label": label,
        "method": "presort_lf_et",
        "samples": samples,
        "exact": True,
        "ms": ms,
        "clock": clock(mhz) if mhz else None,
        "rmse_255": 1.0,
        "edge_rmse_255": 4.0 / samples,
        "flip": None,
        "memory": {},
        "fragments": {},
    }


def record(mhz_x1: float | None, mhz_x4: float | None, top: float | None = 1980) -> dict:
    rows = [row("presort_lf_et hw x1", 1, 26.0, mhz_x1), row("presort_lf_et hw x4", 4, 63.0, mhz_x4)]
    ref = {"method": "presort_lf", "k": 8, "tiles": 16, "edge_tolerance": 0.05}
    rec = {"scene": "s", "size": 1024, "reference": ref, "edge_pixels": 1, "rows": rows}
    return rec | {"max_sm_clock_mhz": top, "warmup_s": 1.5}


def test_below_max_clock():
    assert accuracy_scenes.below_max_clock(clock(765), 1980)
    assert accuracy_scenes.below_max_clock(None, 1980)  # nothing sampled where a maximum exists: not known
    assert not accuracy_scenes.below_max_clock(clock(1980), 1980)
    assert not accuracy_scenes.below_max_clock(None, None)  # no nvidia-smi (llvmpipe): nothing to mark


def test_ratio_refused_and_row_marked_below_max():
    md = accuracy_scenes.markdown(record(765, 1980), "cmd", "GPU")
    assert "| 26.000* | 765 |" in md and "| 63.000 | 1980 |" in md
    assert "no ratio" in md and "presort_lf_et hw x1 at 765 MHz" in md
    assert "4.00x lower" in md  # the error ratio does not depend on the clock
    assert "SM clock maximum: 1980 MHz" in md


def test_ratio_given_at_max_and_without_clock():
    for rec in (record(1980, 1980), record(None, None, top=None)):
        md = accuracy_scenes.markdown(rec, "cmd", "GPU")
        assert "frame time 2.42x" in md and "*" not in md.split("Command")[1].replace("![", "")


def test_old_record_uses_highest_sampled_clock():
    rec = record(765, 1980)
    del rec["max_sm_clock_mhz"]
    assert accuracy_scenes.top_clock(rec) == 1980
    assert "no ratio" in accuracy_scenes.markdown(rec, "cmd", "GPU")


def test_warm_up_runs_before_every_attempt():
    calls = []
    result, sampler, retries = gpu_clock.at_full_clock(
        lambda: calls.append("m") or 7, warm_up=lambda: calls.append("w")
    )
    assert (result, calls[:2]) == (7, ["w", "m"])
    assert len(calls) == 2 * (retries + 1)
