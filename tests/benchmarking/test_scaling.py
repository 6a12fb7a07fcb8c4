"""The scaling benchmark runs end to end at tiny sizes: every part measured, fields of one shared mesh, the budget."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh
import yaml

from guaca_py.benchmarking import scaling
from guaca_py.methods import METHODS
from guaca_py.methods.auto import NVIDIA
from guaca_py.scene.loader import load_scene

SCENE = """\
camera: {position: [0, 2, 5], target: [0, 0.5, 0], fov_y: 40, near: 0.1, far: 50}
lights: [{type: directional, direction: [-0.4, -1, -0.6], intensity: 2}]
nodes:
  - {name: a, mesh: {file: ball.ply}, transform: {translation: [-0.6, 0.5, 0], scale: 0.8},
     material: {description: pbr, uniforms: {albedo: [0.9, 0.3, 0.2], alpha: 0.5}}}
  - {name: b, mesh: {file: ball.ply}, transform: {translation: [0.6, 0.5, -0.5], scale: 0.8},
     material: {description: pbr, uniforms: {albedo: [0.2, 0.5, 0.9], alpha: 0.5}}}
"""


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("scenes")
    trimesh.creation.icosphere(subdivisions=1).export(folder / "ball.ply")
    (folder / "balls.yaml").write_text(SCENE)
    return folder


def run(scenes: Path, out: Path, *extra: str) -> dict:
    argv = ["--scenes", str(scenes), "--scene-names", "balls", "--sizes", "32", "--stereo-scene", "balls"]
    argv += ["--stereo-size", "32", "--field", "1", "3", "--field-scene", "balls", "--size", "32", "--frames", "3"]
    argv += ["--methods", "presort_lf_et", "--raster", "hardware", "--no-stages", "--out", str(out)]
    argv += ["--field-dir", str(out), *extra]
    assert scaling.main(str(Path(scaling.__file__).parents[2] / "benchmarks" / "paper_table.py"), argv) == 0
    return json.loads((out / "scaling.json").read_text())


def test_every_part_is_measured_and_written(gl_context, scenes, tmp_path):
    rec = run(scenes, tmp_path)
    rows = rec["rows"]
    assert [(r["part"], r["width"], r["height"], r["views"], r["count"]) for r in rows] == [
        ("size", 32, 32, 1, None),
        ("stereo", 32, 32, 2, None),
        ("stereo", 32, 64, 1, None),
        ("field", 32, 32, 1, 1),
        ("field", 32, 32, 1, 3),
    ]
    for r in rows:
        assert "skipped" not in r, r
        assert r["loop_wall_ms"] > 0 and r["stored"] > 0
        assert r["ns_per_stored"] == pytest.approx(r["loop_wall_ms"] * 1e6 / r["stored"])
        assert r["pool_bytes"] == r["pool_nodes"] * r["bytes_per_node"] and r["overflow"] == 0
        assert {"geometry", "composite"} <= set(r["passes_ms"])
    pair, one = rows[1], rows[2]
    assert pair["stored"] > 0 and pair["drew"]["hardware"] == 2 * one["drew"]["hardware"]  # both views drawn
    field3 = yaml.safe_load((tmp_path / "field_3.yaml").read_text())
    assert len(field3["nodes"]) == 3 and len({n["mesh"]["file"] for n in field3["nodes"]}) == 1
    assert rows[4]["meshes"] == 1 and rows[4]["mesh_uploads"] <= 1  # one mesh, shared by every copy
    assert len({id(n.mesh) for n in load_scene(tmp_path / "field_3.yaml").nodes}) == 1
    md = (tmp_path / "scaling.md").read_text()
    assert "Command: `python benchmarks/paper_table.py scaling --scenes" in md
    assert "## A stereo pair" in md and "Pair over one frame" in md and "## A field" in md
    assert "Pools over 1.2× the bytes" in md


def test_pool_per_stored_counts_one_view_of_a_shared_pool():
    one = {"pool_bytes": 1200, "bytes_per_node": 40, "stored": 25, "views": 1}
    pair = {**one, "stored": 50, "views": 2}  # two views of 25 nodes each, one pool
    assert scaling.pool_per_stored(one) == pytest.approx(1.2) == scaling.pool_per_stored(pair)
    assert scaling.pool_per_stored({**one, "stored": 0}) is None
    rows = [{**one, "part": "size", "scene": "s", "width": 8, "height": 8, "method": "m", "raster": "auto"}]
    assert scaling.memory_lines(rows)[2] == "- none"
    rows[0]["pool_bytes"] = 1300
    assert scaling.memory_lines(rows)[2] == "- s, 8x8, m (auto): 1.30×"


def test_rows_past_the_budget_are_recorded_as_skipped(gl_context, scenes, tmp_path):
    rows = run(scenes, tmp_path, "--budget-s", "0")["rows"]
    assert len(rows) == 5 and all("time budget spent" in r["skipped"] for r in rows)
    assert "skipped: time budget spent" in (tmp_path / "scaling.md").read_text()


def test_the_alternative_is_the_next_exact_method_of_the_gpu_table():
    alternative = scaling.next_exact_method()
    ranked = [m for m, _ in NVIDIA.ranking()]
    assert alternative != scaling.FIRST_METHOD and METHODS.get(alternative).exact
    assert ranked.index(alternative) == 1 if ranked[0] == scaling.FIRST_METHOD else ranked.index(alternative) == 0


def test_stereo_ratio_pairs_each_configuration_with_its_one_frame():
    rows = [
        {"method": "m", "raster": "auto", "views": 2, "ns_per_stored": 1.05},
        {"method": "m", "raster": "auto", "views": 1, "ns_per_stored": 1.0},
        {"method": "m", "raster": "hardware", "views": 2, "ns_per_stored": 2.0},
    ]
    assert scaling.stereo_ratios(rows) == [("m", "auto", pytest.approx(1.05)), ("m", "hardware", None)]


def test_a_raster_choice_may_name_the_triangle_order(gl_context, scenes, tmp_path):
    # compute/ORDER, as Table 1 takes it: the stereo pair's views at 2048² and one 2048x4096 frame fall on
    # either side of the order bound (raster/choice.py), and this measures both in one order
    extra = ("--raster", "compute/tile", "--stereo-size", "0", "--field")
    rows = run(scenes, tmp_path, *extra)["rows"]
    assert [(r["raster"], r["raster_order"]) for r in rows] == [("compute/tile", "tile")]
    assert rows[0]["drew"] == {"compute": 2, "hardware": 0}
