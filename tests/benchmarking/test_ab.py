"""benchmarks/ab.sh: revisions packed from git and a benchmark run in each tree in turn."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import trimesh

ROOT = Path(__file__).parents[2]
SCENE = """\
camera: {position: [0, 0, 4], target: [0, 0, 0], fov_y: 40, near: 0.1, far: 50}
nodes:
  - {name: a, mesh: {file: ball.ply}, material: {description: unlit, uniforms: {color: [1, 0.5, 0.2], alpha: 0.5}}}
"""

pytestmark = pytest.mark.skipif(
    shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs git and the project's repository"
)


def ab(*args: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(ROOT / "benchmarks" / "ab.sh"), *args], capture_output=True, text=True, env=env)


def test_each_packed_tree_runs_the_benchmark_in_turn(tmp_path):
    env = {**os.environ, "AB_DIR": str(tmp_path / "packs")}
    # two names of one commit (a clone may hold no history): two trees all the same
    sha = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    packed = ab("pack", "HEAD", sha, env=env)
    assert packed.returncode == 0, packed.stderr
    assert sorted(p.name for p in (tmp_path / "packs").iterdir()) == sorted(["HEAD.tgz", f"{sha}.tgz"])
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    trimesh.creation.icosphere(subdivisions=1).export(scenes / "ball.ply")
    (scenes / "ball.yaml").write_text(SCENE)
    args = ["--scenes", str(scenes), "--scene-names", "ball", "--sizes", "32", "--stereo-size", "0", "--field"]
    args += ["--methods", "presort_lf_et", "--raster", "hardware", "--no-stages", "--frames", "2", "--budget-s", "60"]
    run = ab("run", str(tmp_path / "out"), "1", "benchmarks/paper_table.py", "scaling", *args, env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    for name in ("HEAD", sha):
        assert (tmp_path / "out" / f"{name}_1" / "scaling.json").is_file()
        assert f"== {name}, round 1\n| ball | 32x32 | presort_lf_et | hardware |" in run.stdout


def test_bad_input_is_refused_with_what_to_do(tmp_path):
    env = {**os.environ, "AB_DIR": str(tmp_path / "packs")}
    nothing = ab("pack", "no-such-revision", env=env)
    assert nothing.returncode == 2 and "no commit 'no-such-revision'" in nothing.stderr
    empty = ab("run", str(tmp_path / "out"), "1", "benchmarks/aa_cost.py", env=env)
    assert empty.returncode == 2 and "ab.sh pack REV... first" in empty.stderr
    (tmp_path / "packs").mkdir(exist_ok=True)
    (tmp_path / "packs" / "x.tgz").write_bytes(b"")
    rounds = ab("run", str(tmp_path / "out"), "two", "benchmarks/aa_cost.py", env=env)
    assert rounds.returncode == 2 and "ROUNDS must be a positive whole number" in rounds.stderr
