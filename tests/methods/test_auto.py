"""`method: auto`: the fastest exact method of the device's measured table, reported in the stats and by `guaca info`."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from guaca_py import Renderer
from guaca_py.antialiasing import with_samples
from guaca_py.cli import main
from guaca_py.context import probe_capabilities
from guaca_py.errors import ConfigError
from guaca_py.methods import auto, method_class, method_ids
from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.reference.scenes import layered_quads_scene

PIPELINE = """name: auto
transparency: {method: auto, threshold: 0.999%s}
passes: [geometry, {light_culling: {mode: off}}, composite]
"""


@pytest.fixture(scope="module")
def caps():
    return probe_capabilities()


def _nvidia(caps):
    """The capabilities of an NVIDIA GPU (as the H100 reports them), on this machine's limits."""
    return dataclasses.replace(
        caps,
        gl_renderer="NVIDIA H100 80GB HBM3/PCIe/SSE2",
        vendor="NVIDIA Corporation",
        atomic_int64=True,
        fragment_interlock=True,
        software=False,
        framebuffer_fetch=False,
    )


def test_tables_hold_exact_methods_measured_on_every_scene():
    for table in auto.TABLES:
        assert len(table.ms) >= 4 and table.measured
        for scene, row in table.ms.items():
            assert set(row) <= set(method_ids()), (table.name, scene)
            assert all(method_class(m).exact for m in row), (table.name, scene)
            assert all(ms > 0 for ms in row.values())
        ranking = table.ranking()
        assert ranking[0][1] >= 1.0 and [s for _, s in ranking] == sorted(s for _, s in ranking)
    # the table and its ranking: a method that is fastest on every scene scores exactly 1
    one = auto.DeviceTable("t", ("t",), "test", {"a": {"x": 2.0, "y": 4.0}, "b": {"x": 1.0, "y": 1.0}})
    assert one.ranking() == [("x", 1.0), ("y", pytest.approx(2.0**0.5))]


def _llvmpipe(caps):
    """The capabilities of Mesa's llvmpipe (as CI's machines report them), on this machine's limits."""
    return dataclasses.replace(
        caps,
        gl_renderer="llvmpipe (LLVM 15.0.6, 256 bits)",
        vendor="Mesa",
        atomic_int64=False,
        fragment_interlock=False,
        conservative_raster=False,
        software=True,
    )


def test_devices_get_their_table(caps):
    caps = _llvmpipe(caps)  # whichever device runs the suite
    llvmpipe, measured = auto.table_for(caps)
    assert (llvmpipe.name, measured) == ("llvmpipe", True)
    mid, why = auto.choose(caps)
    assert mid == llvmpipe.ranking()[0][0] and why.startswith("fastest exact method measured on llvmpipe:")
    # NVIDIA: the sorted lock-free A-buffer with early termination (fastest or within 6 % on Table 1's scenes)
    mid, why = auto.choose(_nvidia(caps))
    assert mid == "presort_lf_et" and "H100" in why
    # a device nobody measured: the GPU table, said so
    other = dataclasses.replace(_nvidia(caps), gl_renderer="Radeon RX 7900", vendor="AMD")
    assert auto.table_for(other) == (auto.NVIDIA, False)
    assert "not measured" in auto.choose(other)[1]


def test_choice_respects_samples_and_device(caps):
    for c in (caps, _nvidia(caps)):
        mid, why = auto.choose(c, samples=4)
        assert method_class(mid).supports_antialiasing and method_class(mid).unsupported_reason(c) is None
        table, _ = auto.table_for(c)
        unsupported = [m for m, _ in table.ranking() if not method_class(m).supports_antialiasing]
        if table.ranking()[0][0] in unsupported:
            assert f"that runs here at 4 samples ({table.ranking()[0][0]}" in why


def test_renderer_method_auto_reports_its_pick_and_renders_like_it(renderer_factory, caps):
    scene = layered_quads_scene(12)
    r = renderer_factory("exact", method="auto")
    frame = r.render(scene, 64, 48)
    chosen, why = auto.choose(caps)
    assert frame.stats["method"] == chosen == r.method.id and frame.stats["method_auto"] == why == r.method_auto
    same = renderer_factory("exact", method=chosen).render(scene, 64, 48)
    assert "method_auto" not in same.stats
    assert np.abs(frame.image.astype(int) - same.image.astype(int)).max() <= 1
    # presort_lf_et stays selectable by name
    r.set_method("presort_lf_et")
    assert r.method.id == "presort_lf_et" and "method_auto" not in r.render(scene, 64, 48).stats


def test_pipeline_method_auto_takes_settings_of_the_methods_it_may_pick(renderer_factory):
    config = pipeline_from_text(PIPELINE % "", "auto.yaml")
    assert config.transparency == {"method": "auto", "threshold": 0.999}
    r = renderer_factory(config)
    assert r.method.settings["threshold"] == 0.999 and r.method_auto
    # a setting only some candidates have is accepted (the picked method takes it where it has it)
    paged = pipeline_from_text(PIPELINE % ", page_size: 8", "auto.yaml")
    assert paged.transparency["page_size"] == 8
    # a setting none of them has is refused with the file and line
    with pytest.raises(ConfigError, match=r"auto.yaml:2.*unknown setting 'lock_spin'"):
        pipeline_from_text(PIPELINE % ", lock_spin: 3", "auto.yaml")
    # antialiasing: auto picks among the methods that resolve samples
    four = renderer_factory(with_samples(load_pipeline("exact"), 4, "test"), method="auto")
    assert method_class(four.method.id).supports_antialiasing


def test_unknown_method_names_auto(tmp_path):
    with pytest.raises(ConfigError, match="or auto"):
        pipeline_from_text(PIPELINE.replace("auto,", "fastest,") % "", "bad.yaml")
    with pytest.raises(ConfigError, match="or auto"):
        Renderer("exact", method="fastest")


def test_cli_render_and_info_report_auto(tmp_path, capsys, caps):
    chosen, why = auto.choose(caps)
    out, stats = tmp_path / "a.png", tmp_path / "a.json"
    args = ["render", "--method", "auto", "--width", "32", "--height", "24", "--out", str(out), "--stats", str(stats)]
    assert main([*args, "--set", "threshold=0.99"]) == 0
    saved = json.loads(stats.read_text())
    assert saved["method"] == chosen and saved["method_auto"] == why
    assert f"method {chosen}" in capsys.readouterr().out
    assert main(["info"]) == 0
    assert f"transparency method (method: auto): {chosen}" in capsys.readouterr().out
    assert main(["info", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["method_auto"] == {"method": chosen, "why": why}
