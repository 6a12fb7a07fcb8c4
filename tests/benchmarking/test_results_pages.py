"""Every committed results page is what its benchmark writes from the record beside it (Results.finish)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
# a results folder's page -> the command that rebuilds it from the JSON beside it (--out and --replot added)
REPLOT = {
    ("aa_cost", "aa_cost.md"): ["benchmarks/aa_cost.py"],
    ("breaking_points", "breaking_points.md"): ["benchmarks/breaking_points.py"],
    ("light_culling", "light_culling.md"): ["benchmarks/light_culling.py"],
    ("methods_table", "methods_table.md"): ["benchmarks/methods_table.py"],
    ("paper_table", "paper_table.md"): ["benchmarks/paper_table.py"],
    ("paper_table", "scaling.md"): ["benchmarks/paper_table.py", "scaling"],
    ("peeling_vs_vtk", "peeling_vs_vtk.md"): ["benchmarks/peeling_vs_vtk.py"],
    ("raster_sweep", "raster_sweep.md"): ["benchmarks/raster_sweep.py"],
    ("accuracy_scenes", "aa_chart.md"): ["benchmarks/accuracy_scenes.py", "--aa-chart"],
}


# pages whose writer has no --replot (python -m guaca_py.batch.bench writes page and record in one go)
NOT_REPLOTTED = {("batch", "batch.md")}


def pages() -> list[Path]:
    return sorted(p for p in RESULTS.glob("*/*/*.md") if (p.parent.name, p.name) in REPLOT)


@pytest.mark.parametrize("page", pages(), ids=lambda p: f"{p.parent.parent.name}/{p.parent.name}/{p.name}")
def test_committed_page_is_its_record_replotted(tmp_path, page):
    copy = tmp_path / page.parent.name
    shutil.copytree(page.parent, copy)
    (copy / page.name).unlink()
    cmd = [sys.executable, *REPLOT[page.parent.name, page.name], "--out", str(copy), "--replot"]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (copy / page.name).read_text() == page.read_text(), f"{page} differs from what its JSON gives"


def test_every_page_with_a_record_is_checked():
    """A results page beside a JSON record of the same name is in REPLOT (so the test above covers it)."""
    unchecked = [
        p
        for p in RESULTS.glob("*/*/*.md")
        if p.with_suffix(".json").is_file() and (p.parent.name, p.name) not in REPLOT.keys() | NOT_REPLOTTED
    ]
    assert not unchecked, unchecked
