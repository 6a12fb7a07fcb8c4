"""The benchmark harness: clock rules (rows below the maximum SM clock are marked and never compared),
results folders per device, progress lines, a benchmark's table rebuilt from its JSON, its scenes folder."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from guaca_py.benchmarking import (
    Progress,
    Results,
    at_full_clock,
    below_max_clock,
    bench_args,
    device_slug,
    ratio_at_full_clock,
    timer_sentence,
    top_clock,
)

ROOT = Path(__file__).resolve().parents[2]


def clock(mhz: float) -> dict:
    return {"sm_clock_mhz_median": mhz, "sm_clock_mhz_min": mhz, "sm_clock_mhz_max": mhz, "sm_clock_samples": 3}


def row(label: str, samples: int, ms: float, mhz: float | None) -> dict:
    return {
        "label": label,
        "method": "presort_lf_et",
        "samples": samples,
        "exact": True,
        "ms": ms,
        "timer": "gpu",
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
    rec = {"scene": "s", "size": 1024, "reference": ref, "edge_pixels": 1, "rows": rows, "device": "GPU"}
    return rec | {"max_sm_clock_mhz": top, "warmup_s": 1.5, "command": "cmd"}


def test_below_max_clock():
    assert below_max_clock(clock(765), 1980)
    assert below_max_clock(None, 1980)  # nothing sampled where a maximum exists: not known
    assert not below_max_clock(clock(1980), 1980)
    assert not below_max_clock(None, None)  # no nvidia-smi (llvmpipe): nothing to mark


def test_ratio_only_between_rows_at_the_maximum_clock():
    one, four = row("a", 1, 26.0, 1980), row("b", 4, 63.0, 765)
    assert ratio_at_full_clock(one, four, 1980) is None
    assert ratio_at_full_clock(one, row("b", 4, 63.0, 1980), 1980) == 63.0 / 26.0
    assert ratio_at_full_clock(row("a", 1, 26.0, None), row("b", 4, 52.0, None), None) == 2.0


def test_old_record_uses_highest_sampled_clock():
    rec = record(765, 1980)
    assert top_clock(rec) == 1980
    del rec["max_sm_clock_mhz"]
    rec["rows"][1]["clock"] = clock(1755)
    assert top_clock(rec) == 1755
    assert top_clock(record(None, None, top=None)) is None


def test_warm_up_runs_before_every_attempt():
    calls = []
    result, sampler, retries = at_full_clock(lambda: calls.append("m") or 7, warm_up=lambda: calls.append("w"))
    assert (result, calls[:2]) == (7, ["w", "m"])
    assert len(calls) == 2 * (retries + 1)


def test_device_folder_names():
    assert device_slug("NVIDIA H100 80GB HBM3/PCIe/SSE2") == "h100"
    assert device_slug("llvmpipe (LLVM 15.0.6, 256 bits)") == "llvmpipe"
    assert device_slug("NVIDIA H200/PCIe/SSE2") == "nvidia_h200"
    assert device_slug("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 17.0.6)") == "amd_radeon_rx_7900_xtx"


def test_results_folder_and_command(tmp_path):
    script = str(ROOT / "benchmarks" / "paper_table.py")
    args = bench_args(script, "Doc.", size=64).parse_args(["--size", "32"])
    res = Results(args, "NVIDIA H100 80GB HBM3/PCIe/SSE2", ["--size", "32"])
    assert res.dir == ROOT / "benchmarks" / "results" / "h100" / "paper_table"
    assert res.command == "python benchmarks/paper_table.py --size 32"
    args = bench_args(script, "Doc.", size=64).parse_args(["--out", str(tmp_path)])
    res = Results(args, "llvmpipe (LLVM 15.0.6, 256 bits)", ["--out", str(tmp_path)])
    written = json.loads(res.write_json({"rows": [1]}).read_text())
    assert written == {"device": "llvmpipe (LLVM 15.0.6, 256 bits)", "command": res.command, "rows": [1]}


def test_wall_time_is_labelled_as_such():
    assert "GPU timer" in timer_sentence("gpu") and "wall" not in timer_sentence("gpu")
    assert "**wall time**" in timer_sentence("wall") and "no GPU performance figure" in timer_sentence("wall")


def test_progress_counts_and_estimates(capsys):
    p = Progress(4)
    p.step("first")
    p.step("second")
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("[  1/4 ") and lines[1].startswith("[  2/4 ") and "ETA" in lines[1]
    assert lines[1].endswith("] second")


def replot_accuracy(tmp_path: Path, rec: dict) -> str:
    """accuracy_scenes.py --replot over a record written by hand: the page it writes."""
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "accuracy.json").write_text(json.dumps(rec))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    cmd = [sys.executable, "benchmarks/accuracy_scenes.py", "--out", str(tmp_path), "--replot"]
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True, timeout=120)
    assert "[s](s/accuracy.md)" in (tmp_path / "README.md").read_text()
    return (tmp_path / "s" / "accuracy.md").read_text()


def test_accuracy_page_marks_rows_below_max_and_refuses_their_ratio(tmp_path):
    md = replot_accuracy(tmp_path, record(765, 1980))
    assert "| 26.000* | 765 |" in md and "| 63.000 | 1980 |" in md
    assert "no ratio" in md and "presort_lf_et hw x1 at 765 MHz" in md
    assert "4.00x lower" in md  # the error ratio does not depend on the clock
    assert "SM clock maximum: 1980 MHz" in md and "Times: GPU timer queries" in md


def test_accuracy_page_gives_ratio_without_clock(tmp_path):
    md = replot_accuracy(tmp_path, record(None, None, top=None))
    assert "frame time 2.42x" in md and "*" not in md.split("Command")[1].replace("![", "")


def test_a_scenes_folder_without_scenes_is_an_error(tmp_path):
    """`--scenes MISSING` (or a folder of no YAML) exits non-zero with the reason, not with an empty report."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    (tmp_path / "empty").mkdir()
    for scenes, reason in ((tmp_path / "MISSING", "no such folder"), (tmp_path / "empty", "no scene YAML")):
        cmd = [sys.executable, "benchmarks/accuracy_scenes.py", "--out", str(tmp_path / "out"), "--scenes", str(scenes)]
        r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode != 0 and f"--scenes {scenes}: {reason}" in r.stderr, r.stderr
        assert not (tmp_path / "out").exists()  # nothing written
