"""Bad and extreme inputs: each ends in exit 2 naming the file, line or option and what to do, or in a
correct image with a counted, reported degradation; never in a traceback or a signal.

Cases that could kill the process (pools at the device's limits) run in a subprocess.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from guaca_py.cli import main

ROOT = Path(__file__).resolve().parents[1]
QUAD = "{primitive: quad, size: [10, 10]}"


def scene_text(nodes: str = "", camera: str = "{position: [0, 0, 3], target: [0, 0, 0]}") -> str:
    """A scene YAML with the given node lines (indented list items)."""
    return f"camera: {camera}\nbackground: [0, 0, 0]\nnodes:\n{nodes or '  []'}\n"


def layer(z: float, color=(1, 0, 0), alpha: float = 0.5, material: str = "unlit") -> str:
    """One full-screen quad at depth z (a material other than unlit gets no uniforms)."""
    uniforms = f", uniforms: {{color: {list(color)}, alpha: {alpha}}}" if material == "unlit" else ""
    return f"  - {{mesh: {QUAD}, transform: {{translation: [0, 0, {z}]}}, material: {{description: {material}{uniforms}}}}}\n"


def stack(n: int, back_to_front: bool = True, alpha: float = 0.3) -> str:
    """n full-screen layers, drawn far to near (or near to far)."""
    zs = [-i * 0.01 for i in range(n)]
    order = zs[::-1] if back_to_front else zs
    return "".join(layer(z, ((i * 37) % 255 / 255, (i * 91) % 255 / 255, 0.5), alpha) for i, z in enumerate(order))


def run(args: list[str], capsys) -> tuple[int, str, str]:
    """`guaca render ...` in this process: (exit status, stdout, stderr)."""
    rc = main(["render", *map(str, args)])
    out = capsys.readouterr()
    return rc, out.out, out.err


def run_isolated(args: list[str], env: dict | None = None, timeout: int = 120) -> subprocess.CompletedProcess:
    """`guaca render ...` in a child process, so a crash inside the driver cannot take pytest down."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    e = dict(os.environ, PYTHONPATH=path, **(env or {}))  # keep where the dependencies are installed
    return subprocess.run(
        [sys.executable, "-m", "guaca_py", "render", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=e,
        cwd=ROOT,
    )


def write(path: Path, text: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def expect_error(rc: int, err: str, *needles: str) -> None:
    """Exit 2, one 'error:' line, no traceback, and every needle in the message."""
    assert rc == 2, err
    assert err.startswith("error: ") and "Traceback" not in err, err
    for n in needles:
        assert n in err, f"{n!r} not in {err!r}"


# ---------------------------------------------------------------------------- scene files
def _deep_scene(levels: int) -> str:
    text, indent = "nodes:\n", "  "
    for i in range(levels):
        text += f"{indent}- name: n{i}\n{indent}  children:\n"
        indent += "    "
    return text + f"{indent}- {{mesh: {QUAD}}}\n"


@pytest.mark.parametrize(
    "text,needles",
    [
        (_deep_scene(101), ["nested deeper than 100 levels", "flatten", "'nodes[0].(...99 levels...).children[0]'"]),
        ("nodes:\n  - &a\n    name: loop\n    children: [*a]\n", ["cycle", ":2", "nodes[0].children[0]"]),
        (scene_text(camera="{near: 1.0e-30, far: 100}"), ["far / near", "raise near to at least 5.96e-06"]),
        (scene_text(camera="{near: 1.0e-6, far: 100}"), ["exhausts the 24-bit depth buffer", "collapse"]),
        (scene_text(layer(0).replace("translation: [0, 0, 0]", "scale: 1.0e+8")), ["scale 1e+08 exceeds 1e+07"]),
        (scene_text(camera="{near: 1e-3, far: 100}"), ["YAML reads '1e-3' as text", "1.0e-03"]),
        (scene_text(layer(0).replace("[0, 0, 0]", "[0, 0, 1.0e+9]")), ["reaches 1e+09 units", ":4"]),
        (scene_text(layer(0, alpha="5e-1")), ["'alpha'", "YAML reads '5e-1' as text", "5.0e-01"]),
    ],
)
def test_bad_scene_exits_2_with_location(tmp_path, capsys, text, needles):
    s = write(tmp_path / "s.yaml", text)
    rc, _, err = run([s, "--width", 64, "--height", 64, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, str(s), *needles)


def test_nesting_up_to_the_limit_renders(renderer_factory):
    from guaca_py.scene.loader import load_scene_text

    frame = renderer_factory("exact").render(load_scene_text(_deep_scene(99)), 16, 16)
    assert frame.stats["draws"] == 1


def test_alias_cycle_in_pipeline_passes(tmp_path, capsys):
    p = write(tmp_path / "p.yaml", "passes: &p\n  - geometry: {}\n  - *p\n")
    rc, _, err = run(["--pipeline", p, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, str(p), "cycle")


def test_pipeline_not_utf8(tmp_path, capsys):
    p = write(tmp_path / "p.yaml", b"passes:\n  - geometry: {}  # caf\xe9\n")
    rc, _, err = run(["--pipeline", p, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, f"{p}:2", "not UTF-8 text (byte 0xe9 on line 2)")


def test_pass_listed_twice(tmp_path, capsys):
    text = "passes:\n  - geometry: {}\n  - light_culling: {}\n  - composite: {}\n  - fxaa: {}\n  - fxaa: {}\n"
    p = write(tmp_path / "p.yaml", text)
    rc, _, err = run(["--pipeline", p, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, f"{p}:6", "'fxaa' appears twice (first as passes[3])")


# ---------------------------------------------------------------------------- options
@pytest.mark.parametrize(
    "args,needles",
    [
        (["--width", -5], ["--width", "must be >= 1, got -5"]),
        (["--width", 0, "--height", 0], ["--width", "must be >= 1, got 0"]),
        (["--frames", 0], ["--frames", "must be in [1, 1e+06], got 0"]),
        (["--warmup", -1], ["--warmup", "must be in [0, 1e+06], got -1"]),
        (["--materials", "no/such/dir"], ["--materials", "material directory not found"]),
        (["--set", "max_steps=0"], ["transparency.max_steps", "must be > 0"]),
        (["--set", "max_regrow=-5"], ["transparency.max_regrow", "must be >= 0"]),
        (["--set", "budget_mb=1e9"], ["YAML reads '1e9' as text", "1.0e+09"]),
        (["--set", "budget_mb=["], ["--set", "cannot read '['"]),
    ],
)
def test_bad_option_exits_2_naming_it(tmp_path, capsys, args, needles):
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, _, err = run([s, "--out", tmp_path / "o.png", *args], capsys)
    expect_error(rc, err, *needles)


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--set", "threshold=!!python/object/apply:os.system [x]"], ["cannot read", "unsupported YAML tag"]),
        (["--set", "threshold=[1, ["], ["cannot read", "invalid YAML"]),
        (["--set", "threshold=*a"], ["cannot read", "undefined alias 'a'"]),
        # libyaml stops at its own depth limit ("invalid YAML"), the pure-Python parser at the bound of 64
        (["--set", "threshold=" + "[" * 10000], ["cannot read '[[[", "...': "]),
        (["--set", "threshold=a\0b"], ["cannot read", "character #x0000 is not allowed"]),
        (["--frames", 10**10], ["--frames", "must be in [1, 1e+06], got 10000000000"]),
        (["--warmup", 10**7], ["--warmup", "must be in [0, 1e+06]"]),
    ],
    ids=["python-tag", "syntax", "alias", "deep", "nul", "frames", "warmup"],
)
def test_bad_set_value_or_frame_count_is_one_line(tmp_path, capsys, args, needles):
    """A --set value is read as a pipeline file's values are (bounded, plain tags) and refused in one line;
    a frame count of ten digits is refused instead of running for months."""
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, _, err = run([s, "--out", tmp_path / "o.png", *args], capsys)
    expect_error(rc, err, *needles)
    assert err.count("\n") == 1, err


@pytest.mark.parametrize(
    "args,needles",
    [
        (["--samples", 16], ["--samples:", "'antialiasing.samples'", "must be one of 1, 2, 4, 8, got 16"]),
        (["--set", "threshold=5"], ["--set threshold=5:", "'transparency.threshold'", "must be in (0, 1], got 5"]),
        (["--set", "antialiasing.samples=3"], ["--set antialiasing.samples=3:", "must be one of 1, 2, 4, 8, got 3"]),
        (["--set", "antialiasing.foo=1"], ["--set antialiasing.foo=1:", "unknown setting 'foo'", "known: samples"]),
        (["--set", "nope=1"], ["--set nope=1:", "unknown setting 'nope'", "known: threshold"]),
        (["--set", "nothing"], ["--set:", "expects KEY=VALUE, got 'nothing'"]),
        (["--method", "nope"], ["--method:", "unknown transparency method 'nope'", "known: "]),
        (["--pipeline", "nope"], ["'pipeline': no built-in pipeline 'nope' and no such file", "default, exact"]),
    ],
)
def test_option_errors_name_the_option_not_the_pipeline_file(tmp_path, capsys, args, needles):
    """A bad value given on the command line is reported under its option, never under the pipeline file,
    which does not hold it (it used to read `pipelines/default.yaml: 'antialiasing.samples': ...`)."""
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, _, err = run([s, "--out", tmp_path / "o.png", *args], capsys)
    expect_error(rc, err, *needles)
    assert "default.yaml" not in err and "<input>" not in err, err


def test_api_override_errors_name_the_argument(gl_context):
    """The same for the Python API: a bad method_overrides value or method names the argument."""
    from guaca_py import Renderer
    from guaca_py.antialiasing import with_samples
    from guaca_py.errors import ConfigError
    from guaca_py.pipeline.config import load_pipeline

    with pytest.raises(ConfigError) as err:
        Renderer("default", ctx=gl_context, method_overrides={"threshold": 5})
    assert str(err.value).startswith("method_overrides: 'transparency.threshold': must be in (0, 1]"), err.value
    with pytest.raises(ConfigError) as err:
        Renderer("default", ctx=gl_context, method="nope")
    assert str(err.value).startswith("method: unknown transparency method 'nope'"), err.value
    with pytest.raises(ConfigError) as err:
        with_samples(load_pipeline("default"), 3)
    assert str(err.value).startswith("the samples argument: 'antialiasing.samples'"), err.value
    assert with_samples(load_pipeline("default"), 4, "x").antialiasing["samples"] == 4


def test_frame_beyond_the_device_refused(tmp_path, capsys, gl_context):
    """Wider than the largest render target, or a float target past the storage rule (16384x16384 on llvmpipe)."""
    import math

    from guaca_py.context import detect_capabilities

    lim = detect_capabilities(gl_context).limits
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    wide = lim.max_framebuffer[0] + 1
    rc, _, err = run([s, "--width", wide, "--height", 64, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "--width/--height", f"{wide}x64 exceeds the device's largest render target")
    side = math.isqrt(lim.max_buffer_bytes // 16) + 1
    rc, _, err = run([s, "--width", side, "--height", side, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "--width/--height", "MiB per float render target", "at most about")


def test_multilayer_max_steps_0_refused(tmp_path):
    """It used to be accepted and peel for ever (no insertion can succeed); a child process bounds a regression."""
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    args = [s, "--method", "multilayer_depth_peeling", "--set", "max_steps=0", "--out", tmp_path / "o.png"]
    r = run_isolated(args, timeout=60)
    expect_error(r.returncode, r.stderr, "transparency.max_steps", "must be > 0")


@pytest.mark.parametrize(
    "out,needles",
    [
        ("noext", ["cannot tell the image format from no extension", ".png"]),
        ("o.xyz", ["from '.xyz'"]),
        ("adir", ["is a directory"]),
        ("afile/o.png", ["is a file, not a directory"]),
    ],
)
def test_unwritable_out_rejected_before_rendering(tmp_path, capsys, out, needles):
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("x")
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, stdout, err = run([s, "--out", tmp_path / out], capsys)
    expect_error(rc, err, "--out", *needles)
    assert "rendered" not in stdout  # refused before the render, not after it


def test_read_only_out_and_stats(tmp_path, capsys, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    if os.geteuid() == 0:  # root may write anywhere: let the check see what a user would
        import guaca_py.output

        real = os.access
        monkeypatch.setattr(guaca_py.output.os, "access", lambda p, m: real(p, m) and Path(p) != ro)
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    try:
        rc, _, err = run([s, "--out", ro / "o.png"], capsys)
        expect_error(rc, err, "--out", "not writable")
        rc, _, err = run([s, "--out", tmp_path / "o.png", "--stats", ro / "s.json"], capsys)
        expect_error(rc, err, "--stats", "not writable")
    finally:
        ro.chmod(0o700)


def test_stats_under_a_file_rejected(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, _, err = run([s, "--out", tmp_path / "o.png", "--stats", tmp_path / "afile" / "s.json"], capsys)
    expect_error(rc, err, "--stats", "is a file, not a directory")
    assert not (tmp_path / "o.png").exists()


def test_save_failure_keeps_the_previous_image(tmp_path, monkeypatch):
    from guaca_py.errors import ConfigError
    from guaca_py.pipeline.frame import FrameResult

    out = tmp_path / "out.png"
    FrameResult(np.full((4, 4, 3), 7, np.uint8), {}).save(out)
    good = out.read_bytes()

    def disk_full(self, fp, *a, **k):
        Path(fp).write_bytes(b"\x89PNG partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Image.Image, "save", disk_full)
    with pytest.raises(ConfigError, match="No space left on device"):
        FrameResult(np.zeros((4, 4, 3), np.uint8), {}).save(out)
    assert out.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]  # no temporary file left behind


# ---------------------------------------------------------------------------- materials and meshes
def _material(tmp_path, data, name="m.json") -> Path:
    body = json.dumps(data) if not isinstance(data, bytes) else data
    return write(tmp_path / "mats" / name, body)


_VIS = {"name": "m_vis", "source": ["void m_vis() {", "    gua_color = vec3(1.0);", "}"]}


@pytest.mark.parametrize(
    "data,needles",
    [
        ({"visibility": [{"name": "m_vis", "source": [1, 2]}]}, ["'source' must be a string or a list of lines"]),
        ({"uniforms": [1, 2], "visibility": [_VIS]}, ["'uniforms' must be an object", "uniforms"]),
        (b'{"name": "m", "description": "caf\xe9"}', ["not UTF-8 text (byte 0xe9 on line 1)"]),
        ({"transparent": "yes", "visibility": [_VIS]}, ["'transparent' must be true or false"]),
    ],
)
def test_bad_material_exits_2_with_location(tmp_path, capsys, data, needles):
    _material(tmp_path, data)
    s = write(tmp_path / "s.yaml", scene_text(layer(0, material="m")))
    rc, _, err = run([s, "--materials", tmp_path / "mats", "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "m.json", *needles)


def test_duplicate_material_names_rejected(tmp_path, capsys):
    _material(tmp_path, {"name": "glass", "visibility": [_VIS]}, "a.json")
    _material(tmp_path, {"name": "glass", "visibility": [_VIS]}, "b.json")
    s = write(tmp_path / "s.yaml", scene_text(layer(0, material="glass")))
    rc, _, err = run([s, "--materials", tmp_path / "mats", "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "material name 'glass' is defined twice", "a.json", "b.json")


def test_same_stem_in_two_directories_rejected(tmp_path, capsys):
    for d in ("one", "two"):
        write(tmp_path / d / "m.json", json.dumps({"visibility": [_VIS]}))
    s = write(tmp_path / "s.yaml", scene_text(layer(0, material="m")))
    args = [s, "--materials", tmp_path / "one", "--materials", tmp_path / "two", "--out", tmp_path / "o.png"]
    rc, _, err = run(args, capsys)
    expect_error(rc, err, "material name 'm' is defined twice", str(tmp_path / "one" / "m.json"))


def test_material_found_by_its_name(tmp_path, capsys):
    _material(tmp_path, {"name": "green", "visibility": [_VIS]}, "file_stem.json")
    s = write(tmp_path / "s.yaml", scene_text(layer(0, material="green")))
    rc, _, err = run([s, "--materials", tmp_path / "mats", "--out", tmp_path / "o.png"], capsys)
    assert rc == 0, err


def test_texture_that_is_not_an_image(tmp_path, capsys):
    write(tmp_path / "t.png", "this is text")
    node = f"  - {{mesh: {QUAD}, material: {{description: pbr_textured, uniforms: {{albedo_map: t.png}}}}}}\n"
    s = write(tmp_path / "s.yaml", scene_text(node))
    rc, _, err = run([s, "--width", 64, "--height", 64, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "t.png", "is not a readable image")


def test_texture_beyond_the_device_size(tmp_path, capsys, gl_context):
    from guaca_py.scene.texture import MAX_TEXTURE_SIDE

    device = int(gl_context.info["GL_MAX_TEXTURE_SIZE"])
    most = min(device, MAX_TEXTURE_SIDE)  # the decoder's own bound refuses first on devices of larger textures
    limit = f"the device's largest is {device}x{device}" if device <= MAX_TEXTURE_SIDE else "the largest read is"
    Image.new("RGB", (most + 1, 1)).save(tmp_path / "wide.png")
    node = f"  - {{mesh: {QUAD}, material: {{description: pbr_textured, uniforms: {{albedo_map: wide.png}}}}}}\n"
    s = write(tmp_path / "s.yaml", scene_text(node))
    rc, _, err = run([s, "--width", 64, "--height", 64, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "wide.png", f"is {most + 1}x1; {limit}", "scale")


def test_obj_with_latin1_comment_loads(tmp_path, capsys):
    write(tmp_path / "m.obj", b"# caf\xe9\nv -9 -9 0\nv 9 -9 0\nv 0 9 0\nf 1 2 3\n")
    node = "  - {mesh: {file: m.obj}, material: {description: unlit, uniforms: {color: [0, 1, 0]}}}\n"
    s = write(tmp_path / "s.yaml", scene_text(node))
    out = tmp_path / "o.png"
    rc, _, err = run([s, "--pipeline", "exact", "--width", 64, "--height", 64, "--out", out], capsys)
    assert rc == 0, err
    assert tuple(np.asarray(Image.open(out))[40, 32]) == (0, 255, 0)


_HELPER = [
    "void set_alpha(inout float a) { a = 0.5; }",
    "void m_vis() {",
    "    gua_color = vec3(0.0, 1.0, 0.0);",
    "    gua_unlit = true;",
    "    set_alpha(gua_alpha);",
    "}",
]
_DEFINE = [
    "#define OPACITY gua_alpha",
    "void m_vis() {",
    "    gua_color = vec3(0.0, 1.0, 0.0);",
    "    gua_unlit = true;",
    "    OPACITY = 0.5;",
    "}",
]


@pytest.mark.parametrize("source", [_HELPER, _DEFINE], ids=["inout", "define"])
def test_alpha_the_classifier_cannot_read_stays_transparent(tmp_path, capsys, source):
    """Green at alpha 0.5 over an opaque red quad: (127 or 128, 127 or 128, 0), not opaque green."""
    _material(tmp_path, {"visibility": [{"name": "m_vis", "source": source}]})
    nodes = layer(-0.5, (1, 0, 0), 1.0) + layer(0, material="m")
    s = write(tmp_path / "s.yaml", scene_text(nodes))
    out = tmp_path / "o.png"
    args = [s, "--pipeline", "exact", "--materials", tmp_path / "mats", "--width", 64, "--height", 64, "--out", out]
    rc, _, err = run(args, capsys)
    assert rc == 0, err
    r, g, b = (int(v) for v in np.asarray(Image.open(out))[32, 32])
    assert abs(r - 127.5) <= 1 and abs(g - 127.5) <= 1 and b == 0


def test_material_states_opaque(tmp_path):
    from guaca_py.materials import load_material

    m = load_material(_material(tmp_path, {"transparent": False, "visibility": [{"name": "m_vis", "source": _HELPER}]}))
    assert not m.is_transparent({})
    m = load_material(_material(tmp_path, {"visibility": [{"name": "m_vis", "source": _HELPER}]}, "n.json"))
    assert m.is_transparent({})


# ---------------------------------------------------------------------------- device limits
def test_index_limit_is_two_gib_unless_measured_larger():
    from guaca_py.limits import INDEX_LIMIT_BYTES, NVIDIA_INDEX_LIMIT_BYTES, index_limit_bytes

    # llvmpipe's signed 32-bit byte offsets; NVIDIA indexes 3 GiB (word indices stay below 2^31)
    assert index_limit_bytes("Mesa", True)[0] == INDEX_LIMIT_BYTES == 2**31 - 1
    assert index_limit_bytes("NVIDIA Corporation", False)[0] == NVIDIA_INDEX_LIMIT_BYTES
    assert NVIDIA_INDEX_LIMIT_BYTES // 4 < 2**31
    assert index_limit_bytes("NVIDIA Corporation", True)[0] == INDEX_LIMIT_BYTES  # a software path on it
    assert index_limit_bytes("AMD", False)[0] == INDEX_LIMIT_BYTES  # not measured: the safe bound


def test_limits_follow_one_rule(gl_context):
    from guaca_py.context import detect_capabilities
    from guaca_py.limits import index_limit_bytes
    from guaca_py.methods import method_class
    from guaca_py.renderer import method_settings

    caps = detect_capabilities(gl_context)
    lim = caps.limits
    assert 0 < lim.max_buffer_bytes <= index_limit_bytes(gl_context.info["GL_VENDOR"], caps.software)[0]
    if lim.available_bytes:
        assert lim.max_buffer_bytes <= lim.available_bytes // 2
    m = method_class("presort_lf")(method_settings("presort_lf", {}), caps)
    pixels = 512 * 512
    nodes = m.max_capacity(pixels)
    assert nodes * 32 <= lim.max_buffer_bytes  # node payloads
    assert (pixels + nodes) * m.link_bytes <= lim.max_buffer_bytes  # heads and links
    assert (nodes + 1) * 32 > lim.max_buffer_bytes or (pixels + nodes + 1) * m.link_bytes > lim.max_buffer_bytes


def _buffers_within(memory: dict, cap: int) -> bool:
    """Every buffer a frame reports within `cap` bytes (the A-buffer pool's figure holds payload and links)."""
    for name, v in memory.items():
        if name in ("abuffer_pool", "abuffer_pool_used"):
            v = v // memory["abuffer_node_bytes"] * 32  # the payload buffer; links are checked by the caller
        if v > cap:
            return False
    return True


def _stats(path: Path) -> dict:
    return json.loads(path.read_text())


def test_pool_limit_300_layers_back_to_front(tmp_path):
    """The default pipeline on a 300-layer stack under a 4 MiB cap: renders, stays within it, reports the drop."""
    s = write(tmp_path / "s.yaml", scene_text(stack(300)))
    st = tmp_path / "s.json"
    # a back-to-front stream is the subject: the hardware rasterizer keeps the submission order (the
    # compute one, which `auto` picks on GPUs, sorts front to back and early termination drops the rest)
    args = [s, "--set", "raster=hardware", "--width", 64, "--height", 64, "--out", tmp_path / "o.png", "--stats", st]
    r = run_isolated(args, {"GUACA_MAX_BUFFER_MB": "4"})
    assert r.returncode == 0, r.stderr
    stats = _stats(st)
    cap = 4 * 2**20
    nodes = stats["memory"]["abuffer_pool"] // stats["memory"]["abuffer_node_bytes"]
    link = stats["memory"]["abuffer_node_bytes"] - 32
    assert nodes * 32 <= cap and (64 * 64 + nodes) * link <= cap and _buffers_within(stats["memory"], cap)
    fr = stats["fragments"]
    assert fr["overflow"] > 0 and fr["stored"] + fr["overflow"] == 300 * 64 * 64
    assert "device's limit" in r.stderr and "GUACA_MAX_BUFFER_MB" in r.stderr
    img = np.asarray(Image.open(tmp_path / "o.png"))
    assert img.shape == (64, 64, 3) and img.any()


@pytest.mark.parametrize(
    "method,setting",
    [
        ("presort_lf_et", "budget_mb=1.0e+9"),
        ("multilayer_depth_peeling", "pool_mb=1.0e+9"),
        ("dfb", "budget_mb=1.0e+9"),
    ],
)
def test_huge_budgets_are_capped_not_crashing(tmp_path, method, setting):
    s = write(tmp_path / "s.yaml", scene_text(stack(6)))
    st = tmp_path / "s.json"
    args = [s, "--pipeline", "exact", "--method", method, "--set", setting, "--width", 64, "--height", 64]
    r = run_isolated([*args, "--out", tmp_path / "o.png", "--stats", st], {"GUACA_MAX_BUFFER_MB": "8"})
    assert r.returncode == 0, r.stderr
    stats = _stats(st)
    assert stats["fragments"]["stored"] == 6 * 64 * 64 and not stats.get("warnings")
    assert _buffers_within(stats["memory"], 8 * 2**20)


@pytest.mark.parametrize("method", ["presort_lf", "dfb", "sbuffer", "paged_ll"])
def test_storage_cap_same_rule_for_every_method(renderer_factory, method, monkeypatch):
    """Under one cap, every A-buffer and counted method stores what fits, drops and counts the rest, and says why."""
    from guaca_py.scene.loader import load_scene_text

    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "0.25")  # 8192 fragments of 32 bytes
    r = renderer_factory("exact", method=method)
    frame = r.render(load_scene_text(scene_text(stack(4))), 64, 64)
    fr = frame.stats["fragments"]
    dropped = fr.get("dropped", fr["overflow"])
    assert 0 < fr["stored"] <= 8192 and dropped > 0
    assert any("GUACA_MAX_BUFFER_MB" in w for w in frame.stats["warnings"]), frame.stats["warnings"]
    assert not any("page_size" in w or "budget_mb" in w for w in frame.stats["warnings"])


@pytest.mark.parametrize(
    "method,setting,key",
    [
        ("kbuffer", "k=64", "transparency.k"),
        ("stochastic", "samples=32", "transparency.samples"),
        ("multilayer_depth_peeling", "layers_per_pass=32", "transparency.layers_per_pass"),
    ],
)
def test_fixed_per_pixel_storage_beyond_the_cap_is_refused(tmp_path, capsys, monkeypatch, method, setting, key):
    """Storage without an overflow path (k slots, S samples, M slots per pixel) is refused, naming the setting."""
    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "0.25")
    s = write(tmp_path / "s.yaml", scene_text(stack(2)))
    rc, _, err = run(
        [s, "--method", method, "--set", setting, "--width", 64, "--height", 64, "--out", tmp_path / "o.png"], capsys
    )
    expect_error(
        rc, err, key, "the device holds 0.25 MiB per buffer, lowered by GUACA_MAX_BUFFER_MB", "or the resolution"
    )


def test_auto_regrowth_sizes_to_the_need(renderer_factory):
    """Front to back with early termination: the overflowed first guess must not size the pool to every fragment."""
    from guaca_py.scene.loader import load_scene_text

    r = renderer_factory("exact", method="presort_lf_et")
    frame = r.render(load_scene_text(scene_text(stack(300, back_to_front=False))), 64, 64)
    mem, fr = frame.stats["memory"], frame.stats["fragments"]
    assert fr["overflow"] == 0 and frame.stats["regrown"] >= 1
    # at most the 4x growth step above the need; it was 15x (a node for every fragment of the stack)
    assert mem["abuffer_pool"] <= 4 * mem["abuffer_pool_used"]
    # the next frames hold what the scene needs: at most 1.2x the nodes stored (+ the 1024 slack)
    for _ in range(2):
        steady = r.render(load_scene_text(scene_text(stack(300, back_to_front=False))), 64, 64)
    mem, fr = steady.stats["memory"], steady.stats["fragments"]
    assert fr["overflow"] == 0 and steady.stats["regrown"] == 0
    assert mem["abuffer_pool"] <= (1.2 * fr["stored"] + 1025) * mem["abuffer_node_bytes"]


# ---------------------------------------------------------------------------- methods above one 64x64 tile
def _random_quads(n: int = 6, seed: int = 1) -> str:
    rng = np.random.default_rng(seed)
    out = ""
    for _ in range(n):
        rot = [round(float(v), 2) for v in rng.uniform(-40, 40, 2)] + [0]
        c = [round(float(v), 3) for v in rng.random(3)]
        z = round(float(rng.uniform(-0.5, 0.5)), 3)
        out += (
            f"  - {{mesh: {{primitive: quad, size: [4, 4]}}, transform: {{translation: [0, 0, {z}], rotation_deg: {rot}}}, "
            f"material: {{description: unlit, uniforms: {{color: {c}, alpha: 0.5}}}}}}\n"
        )
    return scene_text(out, "{position: [0, 0, 4], target: [0, 0, 0], fov_y: 50}")


def _exact_methods() -> list[str]:
    from guaca_py.methods import method_class, method_ids

    return [m for m in method_ids() if method_class(m).exact]


@pytest.fixture(scope="module")
def quads_reference(renderer_factory):
    """Random interpenetrating quads at 400x400 (beyond llvmpipe's 64x64 tiles); presort_lf's image per rasterizer."""
    from guaca_py.scene.loader import load_scene_text

    scene = load_scene_text(_random_quads())
    refs: dict = {}

    def ref(raster: str) -> np.ndarray:
        # the two rasterizers snap vertices a rounding apart and so differ in a few edge pixels
        # (tests/raster/test_compute_raster.py bounds that): exact methods agree given the same coverage
        if raster not in refs:
            r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": raster})
            refs[raster] = r.render(scene, 400, 400).image.astype(int)
        return refs[raster]

    return scene, ref


@pytest.mark.parametrize("method", _exact_methods())
def test_exact_methods_agree_above_llvmpipe_tiles(renderer_factory, quads_reference, method):
    """Multi-layer peeling used to be wrong by 127/255 here: llvmpipe dropped earlier draws of a covered tile."""
    from guaca_py.methods import method_class

    if method_class(method).unsupported_reason(renderer_factory("exact").caps):
        pytest.skip("not on this device")
    scene, ref = quads_reference
    frame = renderer_factory("exact", method=method).render(scene, 400, 400)
    raster = frame.stats.get("raster", {})
    mixed = raster.get("compute_draws", 0) and raster.get("hardware_draws", 0)
    assert not mixed, raster  # one quad size: every draw takes one rasterizer
    ref_img = ref("compute" if raster.get("compute_draws", 0) else "hardware")
    assert np.abs(frame.image.astype(int) - ref_img).max() <= 1


def test_driver_refusal_exits_2(tmp_path, capsys, monkeypatch):
    """A resource the driver refuses (incomplete framebuffer, out of memory) is reported, not a traceback."""
    import moderngl

    from guaca_py.renderer import Renderer

    def refuse(*a, **k):
        raise moderngl.Error("the framebuffer is not complete")

    monkeypatch.setattr(Renderer, "render", refuse)
    s = write(tmp_path / "s.yaml", scene_text(layer(0)))
    rc, _, err = run([s, "--out", tmp_path / "o.png"], capsys)
    expect_error(rc, err, "the OpenGL device refused the request", "lower the resolution")


def test_info_reports_the_storage_rule(capsys, monkeypatch):
    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "64")
    assert main(["info", "--json"]) == 0
    lim = json.loads(capsys.readouterr().out)["limits"]
    assert lim["max_buffer_bytes"] == 64 * 2**20 and "GUACA_MAX_BUFFER_MB" in lim["binding"]
    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "lots")
    assert main(["info"]) == 2
    assert "GUACA_MAX_BUFFER_MB='lots' is not a positive number" in capsys.readouterr().err


def test_compute_raster_buffers_follow_the_storage_rule(renderer_factory, monkeypatch):
    """The compute rasterizer's transformed vertices have no overflow path: past the cap it says so, naming the setting."""
    from guaca_py.errors import LimitError
    from guaca_py.scene.loader import load_scene_text
    from guaca_py.scene.primitives import make_primitive

    monkeypatch.setenv("GUACA_MAX_BUFFER_MB", "0.01")  # 10 KiB per buffer
    r = renderer_factory("exact", method="presort_lf", method_overrides={"raster": "compute"})
    scene = load_scene_text(scene_text(stack(1)))
    scene.nodes[0].mesh = make_primitive("sphere", radius=0.5, segments=64, rings=32)  # ~2k vertices
    with pytest.raises(LimitError) as err:
        r.render(scene, 16, 16)  # the frame's own targets fit the cap
    assert "transparency.raster" in str(err.value) and "raster: hardware" in str(err.value)


@pytest.mark.parametrize("method", ["presort_lf_et", "presort_lf_merge2_et", "presort_cs_et"])
@pytest.mark.parametrize("raster", ["hardware", "compute"])
def test_the_fragment_that_saturates_its_pixel_culls_what_lies_behind(renderer_factory, raster, method):
    """Eight layers of alpha 0.9 near to far: the layer that saturates a pixel moves, once stored, the pixel's
    saturation depth up to itself; the layers behind are culled before insertion, not walked and refused
    (the first of them was, one a pixel, before a stored fragment could saturate)."""
    from guaca_py.scene.loader import load_scene_text

    r = renderer_factory("exact", method=method, method_overrides={"raster": raster})
    text = scene_text(stack(8, back_to_front=False, alpha=0.9))
    frame = r.render(load_scene_text(text), 64, 64)
    fr, pixels = frame.stats["fragments"], 64 * 64
    assert fr["overflow"] == 0 and fr["stored"] + fr["et_dropped"] + fr["et_culled"] == 8 * pixels
    assert fr["stored"] < 8 * pixels  # early termination left layers out
    if raster == "compute" or r.caps.software:  # GPU draws overlap: the hardware's fragments race the store
        assert fr["et_dropped"] <= pixels // 20  # was one a pixel
    # the image is the front layers' composite, as without early termination
    full = renderer_factory("exact", method="presort_lf", method_overrides={"raster": raster})
    assert np.abs(frame.image.astype(int) - full.render(load_scene_text(text), 64, 64).image).max() <= 1
