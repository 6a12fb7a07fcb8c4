"""One registry for passes and methods: the decorator, the look-ups and their errors, and config
validation through it without importing the passes or methods."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from test_imports import import_graph

from guaca_py.errors import ConfigError
from guaca_py.methods import MethodSpec, TransparencyMethod
from guaca_py.registry import METHODS, PASSES, Registry, register

ROOT = Path(__file__).resolve().parent.parent


def test_every_pass_and_method_is_registered_under_its_key():
    assert PASSES.names() == [
        "composite",
        "debug_depth_complexity",
        "debug_light_count",
        "fxaa",
        "geometry",
        "light_culling",
        "tone_mapping",
    ]
    assert len(METHODS.names()) == 20 and {"presort_lf_et", "post_merge16", "depth_peeling"} <= set(METHODS.names())
    assert all(PASSES.get(n).name == n for n in PASSES.names())
    for mid in METHODS.names():
        cls = METHODS.get(mid)
        assert cls.id == mid
        # a count of geometry passes, or the rule `guaca methods` shows where the scene decides
        assert (cls.geometry_passes is None) == bool(cls.geometry_passes_rule), mid


def test_methods_are_one_level_below_the_interface():
    # each class implementing methods derives from TransparencyMethod directly; methods that differ
    # only by options share one class (a MethodSpec each)
    specs = [METHODS.get(m) for m in METHODS.names()]
    assert all(isinstance(s, MethodSpec) for s in specs)
    impls = {s.impl for s in specs}
    assert {c.__name__ for c in impls} == {"ABuffer", "CountedStorage", "ForwardBlend", "KBuffer", "Peeling"}
    assert set(TransparencyMethod.__subclasses__()) == impls
    assert all(c.__mro__ == (c, TransparencyMethod, object) and not c.__subclasses__() for c in impls)
    assert [s.id for s in specs if s.impl.__name__ == "ABuffer"] == [
        "post_merge16",
        "post_sort",
        "presort_cs",
        "presort_cs_et",
        "presort_lf",
        "presort_lf_et",
        "presort_lf_merge2_et",
    ]


def test_register_refuses_a_second_class_under_a_key_and_a_class_without_one():
    things = Registry("thing", "id", "thing", "known things")

    class A:
        id = "a"

    class B:
        id = "a"

    class Nameless:
        id = ""

    assert things.add(A) is A and things.add(A) is A  # registering the same class again is harmless
    with pytest.raises(TypeError, match=r"thing 'a' is registered twice: .*A and .*B"):
        things.add(B)
    with pytest.raises(TypeError, match="no id"):
        things.add(Nameless)
    with pytest.raises(ValueError, match="unknown registry kind 'shader'"):
        register("shader")


def test_unknown_names_list_the_known_ones():
    assert METHODS.unknown("nope") == ("unknown transparency method 'nope'", "known: " + ", ".join(METHODS.names()))
    with pytest.raises(ConfigError) as err:
        PASSES.require("bloom", "--pass")
    assert str(err.value) == "--pass: unknown pass 'bloom' (known passes: " + ", ".join(PASSES.names()) + ")"
    assert PASSES.require("fxaa", "--pass") is PASSES.get("fxaa")


def test_config_validates_through_the_registry_alone():
    # pipeline/config.py reads the registry, never the passes or methods packages
    assert not {
        m for m in import_graph()["guaca_py.pipeline.config"] if m.startswith(("guaca_py.passes", "guaca_py.methods"))
    }
    # and importing no more than the config module finds every pass and method
    code = (
        "from guaca_py.pipeline.config import pipeline_from_text\n"
        "text = 'transparency: {method: dfb}\\npasses: [geometry, light_culling, composite, fxaa]'\n"
        "print(pipeline_from_text(text).transparency['method'])\n"
        "try:\n"
        "    pipeline_from_text('transparency: {method: nope}')\n"
        "except Exception as e:\n"
        "    print(e)\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 0, run.stderr
    first, second = run.stdout.splitlines()
    assert first == "dfb"
    assert "unknown transparency method 'nope' (known: coherent_layer_peeling," in second
