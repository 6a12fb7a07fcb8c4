"""Every committed results page is what its benchmark writes from the record beside it (Results.finish)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
# folder -> the command that rebuilds its pages from the JSON (--out and --replot added)
REPLOT = {
    "aa_cost": ["benchmarks/aa_cost.py"],
    "breaking_points": ["benchmarks/breaking_points.py"],
    "light_culling": ["benchmarks/light_culling.py"],
    "methods_table": ["benchmarks/methods_table.py"],
    "paper_table": ["benchmarks/paper_table.py"],
    "peeling_vs_vtk": ["benchmarks/peeling_vs_vtk.py"],
    "raster_sweep": ["benchmarks/raster_sweep.py"],
    "scaling": ["benchmarks/paper_table.py", "scaling"],
    "accuracy_scenes": ["benchmarks/accuracy_scenes.py", "--aa-chart"],
}
PAGES = {"accuracy_scenes": ["aa_chart.md"], "paper_table": ["paper_table.md"]}  # pages a mode of its own writes


def folders() -> list[Path]:
    return sorted(d for d in RESULTS.glob("*/*") if d.is_dir() and d.name in REPLOT)


@pytest.mark.parametrize("folder", folders(), ids=lambda d: f"{d.parent.name}/{d.name}")
def test_committed_page_is_its_record_replotted(tmp_path, folder):
    copy = tmp_path / folder.name
    shutil.copytree(folder, copy)
    pages = PAGES.get(folder.name) or [p.name for p in folder.glob("*.md") if p.name != "README.md"]
    assert pages, f"{folder}: no page"
    for page in pages:
        (copy / page).unlink()
    cmd = [sys.executable, *REPLOT[folder.name], "--out", str(copy), "--replot"]
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    for page in pages:
        assert (copy / page).read_text() == (folder / page).read_text(), f"{folder.name}/{page} differs from its JSON"
