"""The `guaca` command line: render with stats, overflow reporting, info, errors, python -m."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from guaca_py.cli import main

SCENE = """\
camera: {position: [0, 0, 5], target: [0, 0, 0], up: [0, 1, 0], fov_y: 50, near: 0.1, far: 100}
background: [0.1, 0.1, 0.1]
lights: [{type: point, position: [2, 3, 2], color: [1, 1, 1], intensity: 20, radius: 10}]
nodes:
  - name: back
    mesh: {primitive: quad, size: [4, 4]}
    transform: {translation: [0, 0, -1]}
    material: {description: pbr, uniforms: {albedo: [0.2, 0.8, 0.2]}}
  - name: pane_a
    mesh: {primitive: quad, size: [2, 2]}
    transform: {rotation_deg: [0, 30, 0]}
    material: {description: unlit, uniforms: {color: [1, 0, 0], alpha: 0.5}}
  - name: pane_b
    mesh: {primitive: quad, size: [2, 2]}
    transform: {translation: [0.3, 0.2, 0.5], rotation_deg: [0, -30, 0]}
    material: {description: pbr, uniforms: {albedo: [0, 0, 1], alpha: 0.4}}
"""


@pytest.fixture()
def scene_file(tmp_path):
    p = tmp_path / "scene.yaml"
    p.write_text(SCENE)
    return p


def test_render_writes_png_and_stats(scene_file, tmp_path, capsys):
    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    assert (
        main(["render", str(scene_file), "--width", "64", "--height", "48", "--out", str(out), "--stats", str(stats)])
        == 0
    )
    from PIL import Image

    assert Image.open(out).size == (64, 48)
    s = json.loads(stats.read_text())
    assert {"geometry", "light_culling", "composite"} <= set(s["passes"])
    assert all(p["ms"] >= 0 for p in s["passes"].values())
    assert s["fragments"]["stored"] > 0 and s["fragments"]["overflow"] == 0
    assert s["memory"]["abuffer_pool"] >= s["memory"]["abuffer_pool_used"] > 0
    assert "geometry" in capsys.readouterr().out


def test_tiny_budget_overflow_is_reported(scene_file, tmp_path, capsys):
    # the key may be written as in the pipeline file (transparency.budget_mb) or bare (budget_mb)
    stats = tmp_path / "s.json"
    code = main(
        [
            "render",
            str(scene_file),
            "--pipeline",
            "exact",
            "--width",
            "64",
            "--height",
            "64",
            "--set",
            "transparency.budget_mb=0.001",
            "--out",
            str(tmp_path / "o.png"),
            "--stats",
            str(stats),
        ]
    )
    assert code == 0
    err = capsys.readouterr().err
    assert "overflow" in err.lower()
    assert json.loads(stats.read_text())["fragments"]["overflow"] > 0


def test_bad_inputs_exit_2_with_location(scene_file, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(SCENE.replace("description: unlit", "description: no_such_material"))
    assert main(["render", str(bad), "--out", str(tmp_path / "o.png")]) == 2
    err = capsys.readouterr().err
    assert "unknown material 'no_such_material'" in err and "bad.yaml" in err
    assert main(["render", str(scene_file), "--method", "nope", "--out", str(tmp_path / "o.png")]) == 2
    assert "unknown transparency method" in capsys.readouterr().err
    assert main(["render", str(scene_file), "--pipeline", str(tmp_path / "missing.yaml")]) == 2


def test_unknown_material_cites_scene_line(scene_file, tmp_path, renderer_factory):
    from guaca_py import ConfigError
    from guaca_py.scene.loader import load_scene

    bad = tmp_path / "bad.yaml"
    bad.write_text(SCENE.replace("description: unlit", "description: no_such_material"))
    with pytest.raises(ConfigError) as err:
        renderer_factory("exact").render(load_scene(bad), 16, 16)
    line = next(i for i, l in enumerate(SCENE.splitlines(), 1) if "description: unlit" in l)
    assert err.value.line == line


def test_info_reports_insertion_path(capsys):
    assert main(["info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["insertion_path"] == ("64bit" if info["atomic_int64"] else "32bit")
    assert info["gpu_timers"] is (not info["software"]) or not info["gpu_timers"]


def test_python_dash_m_is_the_same_command():
    r = subprocess.run([sys.executable, "-m", "guaca_py", "methods"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "presort_lf_et" in r.stdout and "exact" in r.stdout
    rows = {line.split()[0]: line.split() for line in r.stdout.splitlines()[1:]}
    assert rows["presort_lf_et"][3] == "yes" and rows["dfb"][3] == "no"  # the 'samples > 1' column
    # 'geometry passes': a count, or the rule where the scene decides
    assert rows["presort_lf_et"][2] == "1" and rows["stochastic"][2] == "2" and rows["depth_peeling"][2] == "layers"


def test_missing_gl_gives_one_clear_error(monkeypatch):
    import moderngl

    from guaca_py import DeviceError
    from guaca_py.context import create_context

    def fail(*a, **k):
        raise RuntimeError("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_context", fail)
    with pytest.raises(DeviceError) as err:
        create_context()
    assert "OpenGL 4.5" in str(err.value) and "apt-get install" in str(err.value)


def test_samples_option_overrides_the_pipeline(scene_file, tmp_path, capsys):
    """--samples N renders with N coverage samples (stats say so); a method without coverage refuses it (exit 2)."""
    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    args = ["render", str(scene_file), "--pipeline", "exact", "--width", "32", "--height", "32"]
    assert main([*args, "--samples", "4", "--out", str(out), "--stats", str(stats)]) == 0
    assert json.loads(stats.read_text())["antialiasing"]["samples"] == 4
    # the same through --set, beside a transparency setting; --samples, given too, wins
    assert main([*args, "--set", "antialiasing.samples=2", "--set", "threshold=0.9", "--stats", str(stats)]) == 0
    aa = json.loads(stats.read_text())["antialiasing"]
    assert aa.get("asked", aa["samples"]) == 2  # a device may render more than asked (llvmpipe: 4 for 2)
    assert main([*args, "--set", "antialiasing.samples=2", "--samples", "1", "--stats", str(stats)]) == 0
    assert json.loads(stats.read_text())["antialiasing"]["samples"] == 1
    capsys.readouterr()
    assert main([*args, "--samples", "4", "--method", "dfb", "--out", str(tmp_path / "b.png")]) == 2
    err = capsys.readouterr().err
    assert "dfb" in err and "antialiasing.samples" in err


def test_a_reader_that_stops_early_ends_no_traceback(scene_file, tmp_path):
    """`guaca render ... | head -1`: the first line arrives, the files are written, no BrokenPipeError trace."""
    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    cmd = [sys.executable, "-m", "guaca_py", "render", str(scene_file), "--width", "32", "--height", "24"]
    cmd += ["--out", str(out), "--stats", str(stats)]
    line = f"{' '.join(cmd)} | head -1"
    r = subprocess.run(["bash", "-o", "pipefail", "-c", line], capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith(f"rendered {out} (32x24)") and len(r.stdout.splitlines()) == 1
    assert "Traceback" not in r.stderr and "BrokenPipeError" not in r.stderr, r.stderr
    assert r.returncode in (0, 141)  # 141: guaca's own status, when head closed the pipe before the last line
    assert out.is_file() and json.loads(stats.read_text())["resolution"] == [32, 24]
    # a reader gone before the first line: every write fails; guaca exits 141, as a shell reports SIGPIPE
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141 and "Traceback" not in err, err
