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


def test_set_supersample_renders_the_larger_frame(scene_file, tmp_path, capsys):
    """--set supersample=2 (no prefix: no method has that setting) renders 2x the size into an image of the size asked."""
    from PIL import Image

    out, stats = tmp_path / "o.png", tmp_path / "s.json"
    args = ["render", str(scene_file), "--width", "24", "--height", "16", "--out", str(out), "--stats", str(stats)]
    assert main([*args, "--set", "supersample=2"]) == 0
    s = json.loads(stats.read_text())
    assert s["antialiasing"]["supersample"] == 2 and s["render_resolution"] == [48, 32] and s["resolution"] == [24, 16]
    assert Image.open(out).size == (24, 16)
    assert main([*args, "--set", "antialiasing.supersample=3"]) == 0
    assert json.loads(stats.read_text())["render_resolution"] == [72, 48]
    capsys.readouterr()
    assert main([*args, "--set", "supersample=5"]) == 2
    err = capsys.readouterr().err
    assert "--set supersample=5" in err and "antialiasing.supersample" in err and "1, 2, 3, 4" in err


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


# ---------------------------------------------------------------------------- bad options, lost files
ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]


def guaca(*args, cwd, prelude: str = "", timeout: int = 120) -> subprocess.CompletedProcess:
    """`guaca ARGS` in a child process (after `prelude`, Python run first in it): status, stdout, stderr."""
    import os

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH")))))
    code = f"{prelude}\nimport sys\nfrom guaca_py.cli import main\nsys.exit(main(sys.argv[1:]))"
    cmd = [sys.executable, "-c", code, *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


def one_error_line(r: subprocess.CompletedProcess, *needles: str) -> None:
    """Exit 2 with one line on stderr, 'error: ...' holding every needle; never a traceback."""
    assert r.returncode == 2, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for n in needles:
        assert n in lines[0], f"{n!r} not in {lines[0]!r}"


def snapshot(folder) -> dict:
    """Every entry of `folder`: its type and, for regular files, the bytes (a changed or new file shows)."""
    import os
    import stat

    out = {}
    for p in sorted(folder.iterdir()):
        st = os.lstat(p)
        out[p.name] = (
            stat.S_IFMT(st.st_mode),
            p.read_bytes() if stat.S_ISREG(st.st_mode) else os.readlink(p) if p.is_symlink() else None,
        )
    return out


@pytest.fixture()
def textured(tmp_path):
    """A scene with a texture and an OBJ mesh beside it, a pipeline and a material folder: the run's inputs."""
    import shutil

    from PIL import Image

    Image.new("RGB", (4, 4), (200, 100, 50)).save(tmp_path / "tex.png")
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "mats").mkdir()
    shutil.copy(ROOT / "materials" / "unlit.json", tmp_path / "mats" / "flat.json")
    flat = json.loads((tmp_path / "mats" / "flat.json").read_text())
    flat["name"] = "flat"
    (tmp_path / "mats" / "flat.json").write_text(json.dumps(flat))
    shutil.copy(ROOT / "pipelines" / "default.yaml", tmp_path / "pipe.yaml")
    (tmp_path / "scene.yaml").write_text(
        SCENE + "  - {mesh: {primitive: quad, size: [1, 1]}, material: {description: pbr_textured, "
        "uniforms: {albedo_map: tex.png}}}\n" + "  - {mesh: {file: tri.obj}, material: {description: flat}}\n"
    )
    (tmp_path / "view.yaml").write_text(  # the same without the folder's material: `guaca view` has no --materials
        (tmp_path / "scene.yaml").read_text().replace("description: flat", "description: unlit")
    )
    return tmp_path


#: a render of the fixture's scene with every input option
RUN = ("render", "scene.yaml", "--pipeline", "pipe.yaml", "--materials", "mats", "--width", "16", "--height", "16")


def test_the_scene_and_its_fixture_render(textured):
    """The fixture is a valid run: what the next tests refuse is the output, not the input."""
    r = guaca(
        "render",
        "scene.yaml",
        "--pipeline",
        "pipe.yaml",
        "--materials",
        "mats",
        "--width",
        "16",
        "--height",
        "16",
        "--out",
        "o.png",
        "--stats",
        "s.json",
        cwd=textured,
    )
    assert r.returncode == 0, r.stderr
    assert (textured / "o.png").is_file() and json.loads((textured / "s.json").read_text())["resolution"] == [16, 16]


@pytest.mark.parametrize(
    "outputs,needles",
    [
        (["--stats", "scene.yaml"], ["'--stats': is the scene file"]),
        (["--stats", "./scene.yaml"], ["'--stats': is the scene file"]),
        (["--stats", "pipe.yaml"], ["'--stats': is the pipeline file"]),
        (["--stats", "mats/flat.json"], ["'--stats': is an input of this run", "flat.json"]),
        (["--out", "tex.png"], ["'--out': is an input of this run", "tex.png"]),
        (["--stats", "tri.obj"], ["'--stats': is an input of this run", "tri.obj"]),
        (["--out", "o.png", "--stats", "o.png"], ["'--stats': names the same file as --out"]),
        (["--out", "link.png"], ["'--out': is an input of this run"]),  # a link to the texture
        (["--out", "fifo.png"], ["'--out': is a FIFO (named pipe)"]),
        (["--stats", "to_fifo.json"], ["'--stats': is a FIFO (named pipe) (through a symbolic link)"]),
        (["--stats", "dangling.json"], ["'--stats': is a symbolic link to a missing file"]),
        (["--out", "dir.png"], ["'--out': is a directory"]),
        (["--stats", "/dev/null"], ["'--stats': is a character device"]),  # only looked at
        (["--out", "x" * 300 + ".png"], ["--out", "304 bytes", "at most 255"]),
        (["--out", "d/" * 2100 + "o.png"], ["--out", "4205 bytes", "at most 4095"]),
        (["--stats", ""], ["--stats: the path is empty"]),
        (["--out", ""], ["--out: the path is empty"]),
    ],
    ids=lambda v: " ".join(x[:24] for x in v),
)
def test_an_output_never_replaces_an_input_or_a_special_file(textured, outputs, needles):
    """Refused with exit 2 naming the option and the clash; the folder is exactly as it was."""
    import os

    os.mkfifo(textured / "fifo.png")
    (textured / "to_fifo.json").symlink_to("fifo.png")
    (textured / "dangling.json").symlink_to("missing.json")
    (textured / "link.png").symlink_to("tex.png")
    (textured / "dir.png").mkdir()
    before = snapshot(textured)
    r = guaca(*RUN, *outputs, cwd=textured)
    one_error_line(r, *needles)
    assert snapshot(textured) == before and "rendered" not in r.stdout


def test_a_fifo_named_as_the_scene_is_refused_by_what_it_is(textured):
    """Exit 2 at once (never blocking on the FIFO) with one line naming it: not 'not found'."""
    import os

    os.mkfifo(textured / "fifo.yaml")
    r = guaca("render", "fifo.yaml", "--out", "o.png", cwd=textured, timeout=60)
    one_error_line(r, "fifo.yaml: scene file is a FIFO, not a regular file")
    assert not (textured / "o.png").exists()


def test_outputs_keep_modes_and_write_through_links(textured):
    """A replaced image keeps its mode; --stats through a link replaces the link's target, the link stays."""
    import os
    import stat

    (textured / "o.png").write_bytes(b"old")
    (textured / "o.png").chmod(0o640)
    (textured / "data").mkdir()
    (textured / "data" / "s.json").write_text("{}")
    (textured / "s.json").symlink_to("data/s.json")
    name = "n" * 246 + ".png"  # a name the old temporary (.NAME.XXXX.tmp.png) made too long
    for out in ("o.png", name):
        r = guaca(*RUN, "--out", out, "--stats", "s.json", cwd=textured)
        assert r.returncode == 0, r.stderr
    assert stat.S_IMODE(os.stat(textured / "o.png").st_mode) == 0o640
    assert (textured / "o.png").read_bytes().startswith(b"\x89PNG") and (textured / name).is_file()
    assert (textured / "s.json").is_symlink() and json.loads((textured / "data" / "s.json").read_text())["passes"]
    assert not [p for p in os.listdir(textured) if p.startswith(".")]  # no temporary left


@pytest.mark.parametrize(
    "args,needles",
    [
        (["render", ""], ["'scene': the path is empty"]),  # was: the demo rendered, exit 0
        (["render", "--pipeline", ""], ["--pipeline: the path is empty"]),  # was: '.: file not found'
        (["render", "--materials", ""], ["--materials: the path is empty"]),  # was: the current folder
        (["render", "--set", "budget_mb=.inf"], ["--set budget_mb=.inf: '.inf' is not a finite number"]),
        (["render", "--set", "threshold=.nan"], ["--set threshold=.nan: '.nan' is not a finite number"]),
        (["render", "--set", "max_steps=99999999999999999999"], ["--set max_steps=99999999999999999999", "32-bit"]),
        (["view", "--headless", "--width", "0"], ["--width: must be >= 1, got 0"]),  # was: cannot open a window
        (["view", "--headless", "--height", "-3"], ["--height: must be >= 1, got -3"]),
        (["view", "--headless", "--frames", "-1"], ["--frames: must be in [0, 1e+06], got -1"]),
        (["view", "--headless", "--screenshot", "shot"], ["'--screenshot': cannot tell the image format"]),
        (["view", "--headless", "--screenshot", "scene.yaml"], ["'--screenshot'", "from '.yaml'"]),
        (["view", "--headless", "--screenshot", "tex.png"], ["'--screenshot': is an input of this run"]),
        (["view", "--headless", "--screenshot", "/dev/null"], ["'--screenshot': is a character device"]),
        (["view", "--headless", "--pipeline", ""], ["--pipeline: the path is empty"]),
        (["render", "--width", "abc"], ["guaca render: argument --width: invalid int value: 'abc'"]),
        (["view", "--view", "nope"], ["guaca view: argument --view: invalid choice: 'nope'"]),
    ],
)
def test_bad_options_exit_2_naming_the_option(textured, args, needles):
    """Each in a child process: one line, exit 2, and no file written (no out.png from a demo render)."""
    if args[0] == "view" and "tex.png" in args:
        # the texture is read while the viewer renders its first frame: that takes the viewer extra
        pytest.importorskip("moderngl_window", reason="guaca view needs the viewer extra (moderngl-window)")
        args = [*args[:1], "view.yaml", *args[1:]]
    before = snapshot(textured)
    one_error_line(guaca(*args, cwd=textured), *needles)
    assert snapshot(textured) == before


def test_an_unreadable_material_folder_is_named(textured, capsys, monkeypatch):
    """Not 'unknown material' later on: the folder and why (root reads any folder, so the refusal is simulated)."""
    import os

    real = os.listdir
    monkeypatch.chdir(textured)

    def listdir(path="."):
        if os.path.abspath(path) == str(textured / "mats"):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path)

    monkeypatch.setattr(os, "listdir", listdir)
    assert main(["render", "scene.yaml", "--materials", "mats", "--out", "o.png"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: mats: '--materials': cannot read the directory: Permission denied"), err
    assert not (textured / "o.png").exists()


INTERRUPT = """
import importlib, os, signal
def interrupted(*a, **k):
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of the command's work
    raise AssertionError("not interrupted")
owner = importlib.import_module({module!r})
*inner, last = {name!r}.split(".")
for part in inner:
    owner = getattr(owner, part)
setattr(owner, last, interrupted)
"""


SIGNAL_DURING_SAVE = """
import os, signal, time
from PIL import Image
def save(self, fp, *a, **k):
    open(fp, "wb").write(b"partial")
    os.kill(os.getpid(), signal.{sig})
    time.sleep(30)
Image.Image.save = save
"""


@pytest.mark.parametrize(
    "command,module,name",
    [
        ((*RUN, "--out", "o.png"), "guaca_py.renderer", "Renderer.render"),
        (("view", "view.yaml", "--headless"), "guaca_py.viewer.window", "run_viewer"),
        (("info",), "guaca_py.context", "probe_capabilities"),
        (("methods",), "guaca_py.context", "probe_capabilities"),
    ],
    ids=["render", "view", "info", "methods"],
)
def test_ctrl_c_exits_130_with_one_line(textured, command, module, name):
    """In every command: status 130, 'interrupted' and nothing else on stderr, no file written."""
    before = snapshot(textured)
    r = guaca(*command, cwd=textured, prelude=INTERRUPT.format(module=module, name=name))
    assert r.returncode == 130 and r.stderr == "interrupted\n", r.stderr
    assert snapshot(textured) == before


def launched(*args, cwd, prelude: str = "") -> subprocess.Popen:
    """`guaca ARGS` started as its console script does (`from guaca_launcher import main`), after `prelude`."""
    import os

    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH")))))
    code = f"{prelude}\nimport sys\nfrom guaca_launcher import main\nsys.exit(main())"
    cmd = [sys.executable, "-c", code, *map(str, args)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=cwd)


def test_the_console_script_is_the_launcher():
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"guaca": "guaca_launcher:main"}


CTRL_C_WHEN_IMPORTED = """
import os, signal, sys
class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C while the module is being imported
        return None
sys.meta_path.insert(0, CtrlC())
"""


@pytest.mark.parametrize("module", ["numpy", "moderngl", "guaca_py.methods", "guaca_py.cli"])
def test_ctrl_c_while_guaca_imports_exits_130_with_one_line(textured, module):
    """Before guaca_py.cli.main runs, the launcher owns Ctrl-C: status 130, 'interrupted', no traceback."""
    before = snapshot(textured)
    p = launched(*RUN, "--out", "o.png", cwd=textured, prelude=CTRL_C_WHEN_IMPORTED.format(module=module))
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130 and err == "interrupted\n", err
    assert snapshot(textured) == before


@pytest.mark.parametrize("delay", [0.1, 0.25, 0.5])
def test_ctrl_c_early_in_the_command_exits_130_with_one_line(textured, delay):
    """A real SIGINT some time after the start, wherever it lands (imports, loading, the render)."""
    import signal
    import time

    # timed from the interpreter's start (it says so on stdout), not from the process's
    p = launched(*RUN, "--out", "o.png", cwd=textured, prelude="print('up', flush=True)")
    assert p.stdout.readline() == "up\n"
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert "Traceback" not in err and p.returncode in (0, 130), err
    assert err == "interrupted\n" if p.returncode == 130 else (textured / "o.png").is_file()


@pytest.mark.parametrize("sig,status,stderr", [("SIGTERM", -15, ""), ("SIGINT", 130, "interrupted\n")])
def test_a_signal_while_writing_keeps_the_old_image_and_no_temporary(textured, sig, status, stderr):
    (textured / "o.png").write_bytes(b"the previous image")
    before = snapshot(textured)
    prelude = SIGNAL_DURING_SAVE.replace("{sig}", sig)
    r = guaca(*RUN, "--out", "o.png", cwd=textured, prelude=prelude)
    assert r.returncode == status and r.stderr == stderr, r.stderr
    assert snapshot(textured) == before  # the old image, and no .gtmp- file beside it


def test_api_sizes_take_numpy_integers_and_name_the_argument(renderer_factory):
    """Renderer.render(scene, np.int64(16), ...) renders; a bad size names `width`, not the command's option."""
    import numpy as np

    from guaca_py.errors import LimitError
    from guaca_py.scene.loader import demo_scene

    r = renderer_factory("default")
    assert r.render(demo_scene(), np.int64(24), np.uint16(16)).image.shape == (16, 24, 3)
    for width, got in ((np.int32(0), "0"), (16.0, "16.0"), (np.float32(3), "3.0"), (np.bool_(True), "True")):
        with pytest.raises(LimitError) as err:
            r.render(demo_scene(), width, 16)
        msg = str(err.value)
        assert msg.startswith("'width': must be a positive integer, got") and got in msg and "--" not in msg, msg
    with pytest.raises(LimitError, match="^'height': must be a positive integer, got -2"):
        r.render(demo_scene(), 16, -2)


def test_ctrl_c_during_an_import_is_raised_again_after_it():
    """A Ctrl-C that lands in an import (import's lock cleanup, a weakref callback, would swallow it; a library's
    `except BaseException` around an optional import would keep it as a broken module) waits 2 ms."""
    import signal
    import time
    import types

    from guaca_py import cli

    def frame(filename, back=None):
        return types.SimpleNamespace(f_code=types.SimpleNamespace(co_filename=filename), f_back=back)

    machinery = frame("<frozen importlib._bootstrap>", frame("guaca_py/scene/mesh_io.py"))
    module_code = frame("trimesh/path/__init__.py", frame("<frozen importlib._bootstrap_external>", machinery))
    with cli._ctrl_c_raised_outside_imports():
        assert signal.getsignal(signal.SIGINT) is cli._ctrl_c
        cli._ctrl_c(signal.SIGINT, module_code)  # no exception here: trimesh would keep it
        cli._ctrl_c(signal.SIGINT, machinery)  # nor here: it would be lost
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0
        with pytest.raises(KeyboardInterrupt):
            time.sleep(1)  # the retry's SIGALRM raises it, outside the import
        with pytest.raises(KeyboardInterrupt):
            cli._ctrl_c(signal.SIGINT, None)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGALRM) == signal.SIG_DFL
