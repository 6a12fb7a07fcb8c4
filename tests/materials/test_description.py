"""Material descriptions from hostile or careless hands: every problem a located ConfigError, every bound cheap."""

from __future__ import annotations

import json
import os
import time

import pytest

from guaca_py import ConfigError
from guaca_py.materials import MaterialRegistry, glsl, load_material

VIS = {"name": "m", "source": ["void m() {", "    gua_color = vec3(1.0);", "}"]}


def material(tmp_path, data, name: str = "m.json"):
    """Write a material file (a dict as indented JSON, text as it is)."""
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else json.dumps(data, indent=2))
    return p


def refused(path, needle: str) -> ConfigError:
    """load_material's ConfigError, checked to contain `needle` and name a file."""
    with pytest.raises(ConfigError) as err:
        load_material(path)
    assert needle in str(err.value) and err.value.file is not None, err.value
    return err.value


# ---------------------------------------------------------------------------- shapes
@pytest.mark.parametrize(
    "data,needle,line",
    [
        ({"uniforms": {"u": {"type": ["float"]}}}, "uniform needs a 'type' out of float", 3),
        ({"uniforms": {"u": {"type": {"float": 1}}}}, "uniform needs a 'type'", 3),
        ({"uniforms": {"u": 5}}, "uniform needs a 'type'", 3),
        ({"description": ["x"]}, "'description' must be text", 2),
        ({"visibility": {"name": "m"}}, "'visibility' must be a list of methods", 2),
    ],
)
def test_wrong_shapes_are_located(tmp_path, data, needle, line):
    err = refused(material(tmp_path, data), needle)
    assert err.line == line, err


@pytest.mark.parametrize(
    "entry,needle",
    [
        ({"name": "m", "file": 5}, "'file' must be a path to a .glsl file, got 5"),
        ({"name": "m", "file": ""}, "'file' must be a path"),
        ({"name": "m", "file": ["a.glsl"]}, "'file' must be a path"),
        ({"name": "m", "file": "a\0.glsl"}, "contains a NUL character"),
        ({"name": "m", "file": "missing.glsl"}, "method source file not found"),
        ({"name": "m", "file": "."}, "is a directory"),
        ({**VIS, "file": "m.glsl"}, "either 'source' or 'file', not both"),
        ({**VIS, "sauce": 1}, "unknown key 'sauce' in method 'm'"),
    ],
)
def test_method_file_and_keys_checked(tmp_path, entry, needle):
    err = refused(material(tmp_path, {"visibility": [entry]}), needle)
    assert err.key == "visibility[0]" and err.line is not None and str(tmp_path / "m.json") in str(err)


def test_method_file_that_is_a_fifo_is_refused_at_once(tmp_path):
    os.mkfifo(tmp_path / "m.glsl")
    t0 = time.perf_counter()
    refused(material(tmp_path, {"visibility": [{"name": "m", "file": "m.glsl"}]}), "not a regular file")
    assert time.perf_counter() - t0 < 1


def test_unreadable_method_file_names_it(tmp_path, monkeypatch):
    """As root, chmod 000 does not stop reading: the refusal is what os.open raises."""
    (tmp_path / "m.glsl").write_text("void m() { gua_color = vec3(1.0); }")
    p = material(tmp_path, {"visibility": [{"name": "m", "file": "m.glsl"}]})
    real_open = os.open

    def denied(path, *a, **k):
        if str(path).endswith("m.glsl"):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr(os, "open", denied)
    err = refused(p, "cannot read method source file")
    assert "m.glsl" in str(err) and "permission denied" in str(err) and err.file == p


def test_unreadable_material_file_names_it(tmp_path, monkeypatch):
    p = material(tmp_path, {"visibility": [VIS]})
    real_open = os.open

    def denied(path, *a, **k):
        if str(path) == str(p):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr(os, "open", denied)
    assert refused(p, "cannot read material file").file == p


# ---------------------------------------------------------------------------- JSON: nesting, duplicates, numbers
def test_deep_json_refused_before_json_recurses(tmp_path):
    p = material(tmp_path, '{"uniforms": {"u": {"type": "float", "default": ' + "[" * 100_000 + "]" * 100_000 + "}}}")
    t0 = time.perf_counter()
    err = refused(p, "nested deeper than 64 levels")
    assert err.line == 1 and time.perf_counter() - t0 < 1
    # brackets inside strings are text, not nesting
    ok = {"description": "[" * 100, "visibility": [VIS]}
    assert load_material(material(tmp_path, ok, "ok.json")).doc == "[" * 100


def test_duplicate_keys_and_long_integers(tmp_path):
    text = '{\n  "name": "a",\n  "uniforms": {},\n  "name": "b"\n}'
    assert refused(material(tmp_path, text), "duplicate key 'name'").line == 4
    text = '{\n  "uniforms": {"n": {"type": "int", "default": ' + "9" * 5000 + "}}\n}"
    assert refused(material(tmp_path, text), "an integer of 5000 digits is out of range").line == 2


@pytest.mark.parametrize(
    "spec,needle",
    [
        ({"type": "int", "default": 1e20}, "beyond the 32-bit integer range"),
        ({"type": "int", "default": 100000000000}, "beyond the 32-bit integer range"),
        ({"type": "float", "default": "1e400"}, "must be a finite number, got inf"),  # json reads 1e400 as inf
        ({"type": "float", "default": "NaN"}, "must be a finite number, got nan"),
        ({"type": "vec3", "default": [1, "Infinity", 0]}, "component must be a finite number, got inf"),
        ({"type": "float", "default": 1e39}, "beyond the 32-bit float range"),
        ({"type": "float", "range": ["NaN", "Infinity"]}, "'range' must be [low, high]"),
        ({"type": "float", "range": [0, "Infinity"]}, "finite numbers otherwise"),
    ],
)
def test_uniform_numbers_finite_and_within_32_bits(tmp_path, spec, needle):
    body = json.dumps(spec)
    for word in ("1e400", "NaN", "Infinity"):  # JSON has no such numbers; Python's json reads them
        body = body.replace(f'"{word}"', word)
    text = '{\n  "uniforms": {\n    "u": ' + body + "\n  }\n}"
    err = refused(material(tmp_path, text), needle)
    assert err.line == 3 and err.key == "u"


def test_instance_values_checked_the_same_way():
    unlit = MaterialRegistry().get("unlit")
    for values, needle in [
        ({"alpha": float("nan")}, "must be a finite number, got nan"),
        ({"color": [1, float("inf"), 0]}, "must be a finite number, got inf"),
        ({"color": [[[1, 0, 0]]]}, "expected vec3 (3 numbers)"),
    ]:
        with pytest.raises(ConfigError) as err:
            unlit.resolve_values(values, ("scene.yaml", 7))
        assert needle in str(err.value) and err.value.line == 7, err.value


def test_int_uniform_beyond_32_bits_from_a_scene(tmp_path):
    import numpy as np

    p = material(tmp_path, {"uniforms": {"n": {"type": "int", "default": 3}}, "visibility": [VIS]})
    mat = load_material(p)
    assert mat.resolve_values({"n": np.int64(7)})["n"] == 7  # numpy numbers are numbers
    with pytest.raises(ConfigError, match="beyond the 32-bit integer range") as err:
        mat.resolve_values({"n": 10**20}, ("s.yaml", 3))
    assert err.value.key == "n" and err.value.line == 3


# ---------------------------------------------------------------------------- code bounds
def _method(lines: list[str]) -> dict:
    return {"visibility": [{"name": "m", "source": ["void m() {", *lines, "    gua_color = vec3(x);", "}"]}]}


def test_macro_bomb_refused_naming_the_method_and_bound(tmp_path):
    defs = ["#define A0 x x x x x x x x x x"] + [f"#define A{i + 1} {' '.join([f'A{i}'] * 10)}" for i in range(9)]
    data = {"visibility": [{"name": "m", "source": [*defs, "void m() { float x = 1.0; float y = A9; }"]}]}
    t0 = time.perf_counter()
    err = refused(material(tmp_path, data), f"holds more than {glsl.MAX_TOKENS:,} tokens after macro expansion")
    assert time.perf_counter() - t0 < 0.5 and err.key == "visibility method 'm'" and err.line == 6  # the source
    recursive = {"visibility": [{"name": "m", "source": ["#define A B", "#define B A", "void m() { A; }"]}]}
    assert refused(material(tmp_path, recursive, "r.json"), "expands recursively").key == "visibility method 'm'"


def test_long_expressions_and_many_statements_refused(tmp_path):
    chained = ["    float x = 0.0" + " + x" * 10_000 + ";"]  # 20,000 terms crashed llvmpipe's compiler
    refused(material(tmp_path, _method(chained)), "tokens after macro expansion")
    many = ["    float x = 0.0;"] + ["    x = x * 0.5;"] * glsl.MAX_STATEMENTS
    refused(material(tmp_path, _method(many)), f"more than {glsl.MAX_STATEMENTS:,} statements")
    big = ["    float x = 0.0;", "    // " + "c" * glsl.MAX_CODE_BYTES]
    refused(material(tmp_path, _method(big)), "more than 64 KiB of code")
    (tmp_path / "big.glsl").write_text("void m() {}\n//" + "c" * glsl.MAX_CODE_BYTES)
    refused(material(tmp_path, {"visibility": [{"name": "m", "file": "big.glsl"}]}), "more than 64 KiB")
    # the bounds are for the material's code together
    half = ["    float x = 0.0;"] + ["    x = x * 0.5;"] * (glsl.MAX_STATEMENTS // 2)
    two = {"displacement": [{"name": "d", "source": ["void d() {", *half, "}"]}], **_method(half)}
    refused(material(tmp_path, two), "statements")


def test_material_macros_end_with_their_method(tmp_path, renderer_factory):
    """A method's macros are undefined after it, so they cannot rewrite the shader code that follows."""
    from conftest import quad_node, simple_scene

    # leaked, the second would turn main()'s call of gua_interface_defaults() into an undeclared function
    src = ["#define RED vec3(1.0, 0.0, 0.0)", "#define gua_interface_defaults no_such_function", "void m() {"]
    uniforms = {"color": {"type": "vec3"}, "alpha": {"type": "float"}}  # what quad_node gives
    p = material(
        tmp_path,
        {
            "uniforms": uniforms,
            "visibility": [{"name": "m", "source": [*src, "    gua_color = RED;", "    gua_unlit = true;", "}"]}],
        },
    )
    m = load_material(p).methods["visibility"][0]
    assert m.source.endswith("}\n\n#undef RED\n#undef gua_interface_defaults")
    scene = simple_scene([quad_node("q", 0, (1, 1, 1), 1.0, material="m")])
    image = renderer_factory("exact", material_paths=[tmp_path]).render(scene, 16, 16).image
    assert tuple(image[8, 8, :3]) == (255, 0, 0)


def test_builtin_materials_within_the_bounds():
    reg = MaterialRegistry()
    for name in reg.names():
        mat = reg.get(name)
        code = [m.code for ms in mat.methods.values() for m in ms]
        assert sum(glsl.code_size(c)[1] for c in code) < glsl.MAX_TOKENS // 10, name


# ---------------------------------------------------------------------------- the registry
def test_registry_survives_fifos_and_bombs_among_its_files(tmp_path):
    os.mkfifo(tmp_path / "pipe.json")
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    material(tmp_path, {"name": "green", "visibility": [VIS]}, "ok.json")
    reg = MaterialRegistry([tmp_path])
    t0 = time.perf_counter()
    assert {"green", "pipe", "deep"} <= set(reg.names()) and time.perf_counter() - t0 < 1
    with pytest.raises(ConfigError, match="not a regular file"):
        reg.get("pipe")
    with pytest.raises(ConfigError, match="nested deeper than 64 levels"):
        reg.get("deep")
    with pytest.raises(ConfigError, match="not a regular file"):
        reg.get(str(tmp_path / "pipe.json"))


def test_unlistable_material_directory_refused(tmp_path, monkeypatch):
    real = os.listdir

    def denied(path="."):
        if str(path) == str(tmp_path):
            raise PermissionError(13, "Permission denied")
        return real(path)

    monkeypatch.setattr(os, "listdir", denied)
    with pytest.raises(ConfigError, match="cannot list material directory: Permission denied") as err:
        MaterialRegistry([tmp_path])
    assert err.value.file == tmp_path and err.value.key == "material_paths"
