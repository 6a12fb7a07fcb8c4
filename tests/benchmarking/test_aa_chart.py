"""The anti-aliasing chart (guaca_py/benchmarking/aa_chart.py, accuracy_scenes.py --aa-chart): its rows and pages."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from guaca_py.benchmarking import aa_chart
from guaca_py.pipeline.frame import FrameResult
from guaca_py.reference import srgb

ROOT = Path(__file__).resolve().parents[2]


def test_the_chart_has_every_way_to_antialias():
    """1 sample with and without FXAA, 2/4/8 samples, supersample 2 and 3, auto: each with its pipeline."""
    rows = {row["label"]: pipeline for row, pipeline in aa_chart.configs()}
    assert list(rows) == [
        "1 sample",
        "1 sample + FXAA",
        "2 samples",
        "4 samples",
        "8 samples",
        "supersample 2",
        "supersample 3",
        "auto",
    ]
    assert [p.name for p in rows["1 sample + FXAA"].passes][-2:] == ["tone_mapping", "fxaa"]
    assert rows["8 samples"].antialiasing["samples"] == 8
    assert rows["supersample 3"].antialiasing == {"samples": 1, "supersample": 3, "auto": False}
    assert rows["auto"].antialiasing["auto"] and rows["1 sample"].antialiasing["samples"] == 1
    assert all(p.transparency["method"] == aa_chart.AA_METHOD for p in rows.values())


def test_an_srgb_frame_is_read_as_linear():
    """The FXAA row's 8-bit sRGB output decodes to linear colour within its quantisation."""
    linear = np.linspace(0, 1, 3 * 64, dtype=np.float32).reshape(8, 8, 3)
    image = np.round(srgb(linear) * 255).astype(np.uint8)
    got = aa_chart.linear_of(FrameResult(image, {}))
    assert np.abs(got - linear).max() < 0.01
    assert aa_chart.linear_of(FrameResult(image, {}, linear)) is linear


def row(label: str, mode: str, ms: float, edge: float, **extra) -> dict:
    base = {"label": label, "mode": mode, "samples": 1, "ms": ms, "edge_rmse_255": edge, "rmse_255": edge / 2}
    return {**base, "flip": 0.01, "fragments": {"stored": 100}, "timer": "gpu", "auto_chose": None, **extra}


def test_the_chart_pages_from_the_records(tmp_path):
    """--aa-chart --replot: one table of every scene's rows (auto's choice named) and one figure, from the JSON."""
    for scene, ss_ms in (("a", 3.0), ("b", 9.0)):
        rec = {"scene": scene, "size": 64, "device": "NVIDIA H100", "command": f"cmd {scene}", "rows": []}
        rec["rows"] = [
            row("1 sample", "none", 1.0, 6.0),
            row("4 samples", "samples", 4.0, 2.0, samples=4),
            row("supersample 2", "supersample", ss_ms, 1.8, render_resolution=[128, 128]),
            row("auto", "auto", ss_ms, 1.8, render_resolution=[128, 128], auto_chose="supersample 2"),
            {"label": "8 samples", "mode": "samples", "samples": 8, "skipped": "refused"},
        ]
        (tmp_path / "aa_chart").mkdir(exist_ok=True)
        (tmp_path / "aa_chart" / f"{scene}.json").write_text(json.dumps(rec))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    cmd = [sys.executable, "benchmarks/accuracy_scenes.py", "--out", str(tmp_path), "--aa-chart", "--replot"]
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True, timeout=120)
    md = (tmp_path / "aa_chart.md").read_text()
    assert "| a | auto | 1 | 3.000 | 1.80 | 0.90 | 0.0100 | 100 | 128x128 | supersample 2 |" in md
    assert "| b | supersample 2 | 1 | 9.000 |" in md and "| a | 8 samples | | skipped: refused |" in md
    assert "Times: GPU timer queries" in md and "`cmd b`" in md
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return
    assert (tmp_path / "aa_chart.png").stat().st_size > 10_000
