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
