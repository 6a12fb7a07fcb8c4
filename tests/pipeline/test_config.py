"""Bad pipeline configs and materials are rejected with file, line, key and reason."""

from __future__ import annotations

import json

import pytest

from guaca_py import ConfigError, ShaderCompileError, load_pipeline, pipeline_from_text
from guaca_py.materials import load_material

GOOD = """\
resolution: [64, 64]
transparency: {method: presort_lf_et, threshold: 0.98}
passes:
  - geometry: {}
  - light_culling: {mode: off}
  - composite: {}
  - tone_mapping: {exposure: 1.5}
"""


def test_builtin_pipelines_load():
    for name in ("default", "exact"):
        cfg = load_pipeline(name)
        assert [p.name for p in cfg.passes][:3] == ["geometry", "light_culling", "composite"]
    assert load_pipeline("exact").pass_settings("tone_mapping") is None


def test_good_pipeline_parses_settings():
    cfg = pipeline_from_text(GOOD, "p.yaml")
    assert cfg.resolution == (64, 64)
    assert cfg.pass_settings("tone_mapping")["exposure"] == 1.5
    assert cfg.pass_settings("light_culling")["mode"] == "off"  # YAML 'off' stays a word


@pytest.mark.parametrize(
    "text,line,needle",
    [
        ("passes: [geometry, light_culling\n", 2, "invalid YAML"),
        (GOOD.replace("tone_mapping", "bloom"), 7, "unknown pass 'bloom'"),
        (
            GOOD.replace(
                "  - geometry: {}\n  - light_culling: {mode: off}\n",
                "  - light_culling: {mode: off}\n  - geometry: {}\n",
            ),
            4,
            "wrong pass order",
        ),
        (GOOD.replace("  - composite: {}\n", ""), 3, "compulsory pass 'composite' is missing"),
        (GOOD.replace("exposure: 1.5", "exposure: -2"), 7, "must be > 0"),
        (GOOD.replace("exposure: 1.5", "exposre: 1"), 7, "unknown setting 'exposre'"),
        (GOOD.replace("threshold: 0.98", "threshold: 1.5"), 2, "must be in (0, 1]"),
        (GOOD.replace("presort_lf_et", "magic_oit"), 2, "unknown transparency method 'magic_oit'"),
        ("colour: red\n" + GOOD, 1, "unknown key 'colour'"),
        (GOOD.replace("[64, 64]", "[64]"), 1, "[width, height]"),
    ],
)
def test_bad_pipeline_rejected_with_location(text, line, needle):
    with pytest.raises(ConfigError) as err:
        pipeline_from_text(text, "bad.yaml")
    msg = str(err.value)
    assert needle in msg
    assert err.value.file == "bad.yaml" and err.value.line == line, msg


def _material(tmp_path, data, name="m.json"):
    p = tmp_path / name
    p.write_text(json.dumps(data, indent=2) if not isinstance(data, str) else data)
    return p


def test_material_json_syntax_error_has_line(tmp_path):
    p = _material(tmp_path, '{\n  "name": "x",\n  "uniforms": {,}\n}')
    with pytest.raises(ConfigError) as err:
        load_material(p)
    assert err.value.line == 3 and "invalid JSON" in str(err.value)


def test_material_bad_uniform_type(tmp_path):
    p = _material(tmp_path, {"name": "x", "uniforms": {"c": {"type": "vec5"}}})
    with pytest.raises(ConfigError, match="type"):
        load_material(p)


def test_material_default_of_wrong_shape(tmp_path):
    p = _material(tmp_path, {"name": "x", "uniforms": {"c": {"type": "vec3", "default": [1, 2]}}})
    with pytest.raises(ConfigError, match=r"vec3 \(3 numbers\)"):
        load_material(p)


def test_material_with_more_samplers_than_texture_units(tmp_path):
    # a material's textures take units 8 to 30 (the light grid has 31): one more is refused at load,
    # naming the uniform that does not fit, instead of sampling the light grid as a texture
    from guaca_py.materials.description import MAX_SAMPLERS

    fits = {f"map{i}": {"type": "sampler2D"} for i in range(MAX_SAMPLERS)}
    assert len(load_material(_material(tmp_path, {"name": "x", "uniforms": fits})).uniforms) == MAX_SAMPLERS
    over = {**fits, "one_more": {"type": "sampler2D"}}
    with pytest.raises(ConfigError, match=f"more than {MAX_SAMPLERS} sampler2D") as err:
        load_material(_material(tmp_path, {"name": "y", "uniforms": over}))
    assert err.value.key == "one_more" and err.value.line is not None


def test_material_method_must_define_function(tmp_path):
    p = _material(tmp_path, {"name": "x", "visibility": [{"name": "m", "source": "void other() {}"}]})
    with pytest.raises(ConfigError, match="void m"):
        load_material(p)


def test_instance_uniform_type_checked():
    from guaca_py.materials import MaterialRegistry

    mat = MaterialRegistry().get("unlit")
    with pytest.raises(ConfigError, match="expected float"):
        mat.resolve_values({"alpha": "half"}, ("scene.yaml", 12))
    with pytest.raises(ConfigError, match="no uniform 'colour'") as err:
        mat.resolve_values({"colour": [1, 0, 0]}, ("scene.yaml", 12))
    assert err.value.line == 12


def test_instance_values_outside_the_declared_range_refused():
    """An alpha of -0.5 used to store every fragment and draw nothing; it is refused with the scene's line."""
    from guaca_py.materials import MaterialRegistry

    reg = MaterialRegistry()
    unlit, pbr = reg.get("unlit"), reg.get("pbr")
    for mat, values, needle in [
        (unlit, {"alpha": -0.5}, "-0.5 is outside [0, 1], the range material 'unlit' (unlit.json) declares"),
        (unlit, {"alpha": 2}, "2.0 is outside [0, 1]"),
        (unlit, {"color": [1, -0.1, 0]}, "[1.0, -0.1, 0.0] is outside [0, inf]"),
        (pbr, {"roughness": 1.5}, "1.5 is outside [0, 1]"),
    ]:
        with pytest.raises(ConfigError) as err:
            mat.resolve_values(values, ("scene.yaml", 12))
        assert needle in str(err.value), err.value
        assert err.value.line == 12 and err.value.key == next(iter(values))
    # the bounds themselves, and an open upper bound, pass
    assert unlit.resolve_values({"alpha": 0, "color": [5, 0, 0]})["alpha"] == 0.0
    assert pbr.resolve_values({"alpha": 1, "roughness": 0})["roughness"] == 0.0


@pytest.mark.parametrize(
    "spec,needle",
    [
        ({"type": "float", "default": 2.0, "range": [0, 1]}, "2.0 is outside [0, 1], the range its 'range' declares"),
        ({"type": "float", "range": [1, 0]}, "'range' must be [low, high] with low <= high"),
        ({"type": "float", "range": [0]}, "'range' must be [low, high]"),
        ({"type": "float", "range": ["0", 1]}, "'range' must be [low, high]"),
        ({"type": "sampler2D", "range": [0, 1]}, "a sampler2D uniform has no range"),
        ({"type": "float", "defualt": 0.5}, "unknown key 'defualt' in uniform 'u'"),
    ],
)
def test_material_uniform_range_and_keys_checked(tmp_path, spec, needle):
    """A material declares each uniform's range (either bound may be null); a bad range, a default outside
    it, or a misspelt key is refused with the material file's line."""
    p = _material(tmp_path, '{\n  "name": "x",\n  "uniforms": {\n    "u": ' + json.dumps(spec) + "\n  }\n}")
    with pytest.raises(ConfigError) as err:
        load_material(p)
    assert needle in str(err.value) and err.value.line == 4 and err.value.key == "u", err.value
    open_top = {"type": "vec2", "default": [3, 0], "range": [0, None]}
    ok = load_material(_material(tmp_path, {"name": "y", "uniforms": {"v": open_top}}))
    assert ok.uniforms["v"].range == (0.0, None)


def test_transparency_decided_from_material():
    from guaca_py.materials import MaterialRegistry

    reg = MaterialRegistry()
    unlit, pbr, glass = reg.get("unlit"), reg.get("pbr"), reg.get("fresnel_glass")
    assert not unlit.is_transparent({"alpha": 1.0})
    assert unlit.is_transparent({"alpha": 0.5})
    assert not pbr.is_transparent(pbr.resolve_values({}))
    assert glass.is_transparent(glass.resolve_values({}))


def test_glsl_error_cites_material_file_and_line(tmp_path, renderer_factory):
    from conftest import quad_node, simple_scene

    _material(
        tmp_path,
        {
            "name": "broken",
            "uniforms": {"alpha": {"type": "float", "default": 0.5}, "color": {"type": "vec3"}},
            "visibility": [
                {
                    "name": "broken",
                    "source": [
                        "void broken() {",
                        "    gua_alpha = alpha;",
                        "    gua_color = vec3(undefined_thing);",
                        "}",
                    ],
                }
            ],
        },
        "broken.json",
    )
    r = renderer_factory("exact", material_paths=[tmp_path])
    scene = simple_scene([quad_node("q", 0, (1, 0, 0), 0.5, material="broken")])
    with pytest.raises(ShaderCompileError) as err:
        r.render(scene, 32, 32)
    msg = str(err.value)
    src_line = next(
        i for i, l in enumerate((tmp_path / "broken.json").read_text().splitlines(), 1) if "undefined_thing" in l
    )
    assert f"broken.json:{src_line}:" in msg, msg
    assert "undefined_thing" in msg
    assert "\n" not in msg and msg.startswith(f"{tmp_path / 'broken.json'}:{src_line}:"), msg  # one line, file first


# ---------------------------------------------------------------------------- YAML: bounded work, located shapes
def _laughs(levels: int = 9, under: str | None = "transparency") -> str:
    """'billion laughs': each level repeats the one before nine times (9**levels strings), under key `under`."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 9)}]" for i in range(1, levels)]
    return f"{under}:\n  " + "\n  ".join(lines) + "\n" if under else "\n".join(lines) + "\n"


def _nested_aliases(levels: int = 60) -> str:
    """Each level repeats the one before twice: 2**levels nodes from 60 short lines."""
    lines = ["a0: &a0 [x, x]"] + [f"a{i}: &a{i} [*a{i - 1}, *a{i - 1}]" for i in range(1, levels)]
    return "passes:\n  - geometry:\n      " + "\n      ".join(lines) + "\n"


def _bounded(call):
    """Run `call`; return (its ConfigError, seconds, peak MB of Python allocations)."""
    import time
    import tracemalloc

    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(ConfigError) as err:
            call()
    finally:
        seconds, peak = time.perf_counter() - t0, tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return err.value, seconds, peak


@pytest.mark.parametrize(
    "text,line",
    [
        (_laughs(), 7),  # under a known key, before its settings are read
        (_laughs(under="colour"), 7),  # under an unknown key: refused before the key is looked at
        (_nested_aliases(), 17),
    ],
)
def test_alias_bombs_refused_before_anything_is_built(text, line):
    err, seconds, peak = _bounded(lambda: pipeline_from_text(text, "bomb.yaml"))
    assert "aliases repeat more than 100,000 nodes" in str(err) and err.file == "bomb.yaml" and err.line == line
    assert seconds < 0.5 and peak < 4, (seconds, peak)


def test_alias_bombs_in_scenes_refused():
    from guaca_py.scene.loader import load_scene_text

    uniform = "nodes:\n  - mesh: {primitive: box}\n    material: {description: unlit, uniforms: {color: *l8}}\n"
    primitive = "nodes:\n  - mesh: {primitive: box, size: *l8}\n"
    for tail in (uniform, primitive, "nodes: [*l8]\n"):
        # the anchors sit under top-level keys a scene does not know: the bound refuses before keys are read
        err, seconds, peak = _bounded(lambda t=tail: load_scene_text(_laughs(under=None) + t, "bomb.yaml"))
        assert "aliases repeat more than" in str(err) and err.line == 6 and seconds < 0.5 and peak < 4


def test_ordinary_aliases_are_shared_not_refused():
    from guaca_py.scene.loader import load_scene_text

    nodes = "".join(
        f"  - {{mesh: *box, material: *glass, transform: {{translation: [{i}, 0, 0]}}}}\n" for i in range(500)
    )
    text = "defaults: &d {mesh: &box {primitive: box}, material: &glass {description: unlit, uniforms: {alpha: 0.5}}}\n"
    with pytest.raises(ConfigError, match="unknown key 'defaults'"):  # the anchors parse; the key is checked
        load_scene_text(text + "nodes:\n" + nodes)
    scene = load_scene_text("nodes:\n  - {mesh: &box {primitive: box}, material: &glass unlit}\n" + nodes)
    assert len(scene.nodes) == 501
    cfg = pipeline_from_text(GOOD.replace("{mode: off}", "&lc {mode: off}") + "  - fxaa: {}\n", "p.yaml")
    assert cfg.pass_settings("light_culling") == {**cfg.pass_settings("light_culling"), "mode": "off"}


def test_alias_uses_are_counted(monkeypatch):
    from guaca_py import yaml_source

    monkeypatch.setattr(yaml_source, "MAX_ALIAS_USES", 3)
    text = "a: &a 1\nb: [*a, *a, *a]\nc: *a\n"
    with pytest.raises(ConfigError, match="more than 3 alias uses") as err:
        yaml_source.load_yaml_text(text, "f.yaml")
    assert err.value.line == 3 and err.value.key == "c"


@pytest.mark.parametrize(
    "text,line,key",
    [
        ("transparency: " + "[" * 900 + "]" * 900 + "\n", 1, "transparency[0].(...61 levels...)[0]"),
        ("".join("  " * i + f"k{i}:\n" for i in range(70)) + "  " * 70 + "x: 1\n", 65, "k0.k1.(...61 levels...).k63"),
        ("passes: &p\n  - geometry: {}\n  - *p\n", 1, "passes[1]"),
    ],
)
def test_nesting_and_cycles_refused_with_line(text, line, key):
    err, seconds, _ = _bounded(lambda: pipeline_from_text(text, "deep.yaml"))
    assert ("nested deeper than 64 levels" in str(err) or "cycle" in str(err)) and seconds < 1
    assert err.line == line and err.key == key, err


def test_scene_yaml_nesting_bounded():
    from guaca_py.scene.loader import load_scene_text
    from guaca_py.yaml_source import MAX_YAML_DEPTH

    deep = "nodes:\n  - mesh: {primitive: box, size: " + "[" * 900 + "1" + "]" * 900 + "}\n"
    with pytest.raises(ConfigError, match=f"nested deeper than {MAX_YAML_DEPTH} levels") as err:
        load_scene_text(deep, "s.yaml")
    assert err.value.line == 2 and err.value.key.startswith("nodes[0]")


@pytest.mark.parametrize(
    "node",
    [
        "{mesh: {primitive: box, size: %s}}",
        "{mesh: {primitive: box}, material: {description: pbr, uniforms: {albedo: %s}}}",
    ],
)
def test_scene_values_nested_to_the_bound_are_refused_not_recursed(node):
    """The scene reader reads values recursively: the YAML bound keeps it within Python's recursion limit."""
    from guaca_py.scene.loader import load_scene_text
    from guaca_py.yaml_source import MAX_YAML_DEPTH

    for levels in (MAX_YAML_DEPTH - 4, MAX_YAML_DEPTH):  # the deepest the bound lets through, and past it
        value = "[" * levels + "1" + "]" * levels
        with pytest.raises(ConfigError) as err:
            load_scene_text("nodes:\n  - " + node % value + "\n", "s.yaml")
        assert "duplicate" not in str(err.value) and err.value.line == 2


@pytest.mark.parametrize("levels", [3_000, 100_000])
def test_runaway_flow_nesting_is_a_located_error(levels):
    """libyaml 0.2.6 refuses flow nesting past 1,000 while scanning, older ones leave it to the composer's bound."""
    err, seconds, peak = _bounded(lambda: pipeline_from_text("a: " + "[" * levels + "]" * levels, "deep.yaml"))
    assert err.line == 1 and "nest" in str(err) and seconds < 1 and peak < 8, (err, seconds, peak)


@pytest.mark.parametrize(
    "text,line,needle",
    [
        ("[1, 2]: 3\n" + GOOD, 1, "a mapping key must be a plain name, got a list"),
        (GOOD.replace("  - composite: {}", "  - {[composite]: {}}"), 6, "a mapping key must be a plain name"),
        (GOOD.replace("  - composite: {}", "  - [composite]"), 6, "each pass is a name or a one-key mapping"),
        (GOOD.replace("{method: presort_lf_et, threshold: 0.98}", "5"), 2, "must be a mapping like"),
        (GOOD.replace("{method: presort_lf_et, threshold: 0.98}", "[1, 2]"), 2, "must be a mapping like"),
        (GOOD.replace("{method: presort_lf_et, threshold: 0.98}", "abc"), 2, "must be a mapping like"),
        (GOOD.replace("presort_lf_et", "[presort_lf_et]"), 2, "unknown transparency method"),
        ("name: [a]\n" + GOOD, 1, "'name' must be text"),
        (GOOD.replace("threshold: 0.98", "threshold: 0.98, threshold: 0.5"), 2, "duplicate key 'threshold'"),
        (GOOD.replace("0.98", "!!float abc"), 2, "'abc' is not a valid !!float"),
        (GOOD.replace("0.98", "!python/object x"), 2, "unsupported YAML tag"),
        (GOOD.replace("0.98", "9" * 5000), 2, "an integer of 5000 digits is out of range"),
        (GOOD.replace("exposure: 1.5", "exposure: 2001-02-30"), 7, "expected int/float, got '2001-02-30'"),
        (GOOD.replace("exposure: 1.5", "exposure: ="), 7, "expected int/float, got '='"),
        ("a: *nowhere\n", 1, "found undefined alias 'nowhere'"),
        ("a: 1\n---\nb: 2\n", 2, "expected a single document"),
    ],
)
def test_wrong_shapes_refused_with_location(text, line, needle):
    with pytest.raises(ConfigError) as err:
        pipeline_from_text(text, "bad.yaml")
    assert needle in str(err.value) and err.value.line == line, err.value


def test_scene_mapping_key_that_is_a_list():
    from guaca_py.scene.loader import load_scene_text

    with pytest.raises(ConfigError, match="a mapping key must be a plain name, got a list") as err:
        load_scene_text("nodes:\n  - mesh: {primitive: box, [1, 2]: 3}\n", "s.yaml")
    assert err.value.line == 2 and err.value.key == "nodes[0].mesh"


def test_yaml_parsed_by_libyaml_where_installed():
    import yaml

    from guaca_py import yaml_source

    assert yaml_source.PARSER is (yaml.CSafeLoader if yaml.__with_libyaml__ else yaml.SafeLoader)
    text = "a: 1\nb:\n  - {c: 2}\n  - [d, 'e', 3.5, true, off, null]\n"
    doc = yaml_source.load_yaml_text(text, "f.yaml")
    assert doc.data == yaml.safe_load(text.replace("off", "'off'")) and doc.line(("b", 1)) == 4


# ---------------------------------------------------------------------------- files: only regular ones, bounded
def test_pipeline_file_that_is_not_a_regular_file(tmp_path):
    import os
    import time

    fifo = tmp_path / "p.yaml"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(ConfigError, match="not a regular file") as err:
        load_pipeline(fifo)  # no writer: opening it for reading must not wait for one
    assert time.perf_counter() - t0 < 1 and err.value.file == fifo
    with pytest.raises(ConfigError, match="is a directory"):
        load_pipeline(tmp_path)
    with pytest.raises(ConfigError, match="contains a NUL character"):
        load_pipeline(str(tmp_path / "p\0.yaml"))
    with pytest.raises(ConfigError, match="not found"):
        load_pipeline(tmp_path / "missing.yaml")
    for nothing in ("", None, 5):
        with pytest.raises(ConfigError, match="expected a pipeline name or a path") as err:
            load_pipeline(nothing)
        assert err.value.key == "pipeline"


def test_unreadable_pipeline_names_the_file(tmp_path, monkeypatch):
    """As root, chmod 000 does not stop reading: the refusal is what os.open raises."""
    import os

    p = tmp_path / "p.yaml"
    p.write_text(GOOD)
    real_open = os.open

    def denied(path, *a, **k):
        if str(path) == str(p):
            raise PermissionError(13, "Permission denied", str(path))
        return real_open(path, *a, **k)

    monkeypatch.setattr(os, "open", denied)
    with pytest.raises(ConfigError, match="cannot read file .*p.yaml: permission denied") as err:
        load_pipeline(p)
    assert err.value.file == p


def test_oversized_pipeline_refused(tmp_path):
    from guaca_py.yaml_source import MAX_CONFIG_BYTES

    p = tmp_path / "p.yaml"
    p.write_text(GOOD + "#" * MAX_CONFIG_BYTES)
    with pytest.raises(ConfigError, match="more than 1 MiB"):
        load_pipeline(p)


# ---------------------------------------------------------------------------- numbers where they enter
@pytest.mark.parametrize(
    "old,new,needle",
    [
        ("threshold: 0.98", "threshold: .nan", "must be a finite number, got nan"),
        ("threshold: 0.98", "budget_mb: .inf", "must be a finite number, got inf"),
        ("threshold: 0.98", "budget_mb: 1.0e+39", "beyond the 32-bit float range"),
        ("tone_mapping: {exposure: 1.5}", "debug_light_count: {max: 100000000000}", "beyond the 32-bit integer range"),
        ("threshold: 0.98", "max_steps: 99999999999999999999", "beyond the 32-bit integer range"),
    ],
)
def test_settings_finite_and_within_32_bits(old, new, needle):
    text = GOOD.replace("presort_lf_et", "multilayer_depth_peeling") if "max_steps" in new else GOOD
    with pytest.raises(ConfigError, match=needle.replace("(", r"\(")) as err:
        pipeline_from_text(text.replace(old, new), "p.yaml")
    assert err.value.line in (2, 7)


@pytest.mark.parametrize("item", ["budget_mb=.inf", "budget_mb=.nan", "threshold=-.inf", "budget_mb=1.0e+300"])
def test_set_option_numbers_checked(tmp_path, capsys, item):
    from guaca_py.cli import main

    rc = main(["render", "--set", item, "--out", str(tmp_path / "o.png"), "--width", "8", "--height", "8"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("error: ") and f"--set {item}" in err and "Traceback" not in err, err
    assert not (tmp_path / "o.png").exists()


def test_huge_budgets_within_float32_still_accepted():
    cfg = pipeline_from_text(GOOD.replace("threshold: 0.98", "budget_mb: 1.0e+30"), "p.yaml")
    assert cfg.transparency["budget_mb"] == 1e30
