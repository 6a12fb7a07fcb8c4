"""The breaking-points sweep: every error it reports is explained by the limit counter it names."""

from __future__ import annotations

import pytest

from guaca_py.benchmarking import breaking_points
from guaca_py.methods import method_class

EXACT_255 = 2.0


@pytest.fixture(scope="module")
def sweep(gl_context):
    return breaking_points.run(gl_context, 48, [2, 12], progress=lambda _: None)


def test_every_config_measured_at_every_depth(sweep):
    assert len(sweep["rows"]) == 2 * len(breaking_points.CONFIGS)
    assert all("rmse_255" in r for r in sweep["rows"]), [r for r in sweep["rows"] if "rmse_255" not in r]


def test_bounded_exact_configs_exact_until_their_counter_fires(sweep):
    for r in sweep["rows"]:
        if method_class(r["method"]).exact and not r["counted"]:
            assert r["max_255"] <= EXACT_255, r
        if r["counter"] not in (None, "early_termination_culled") and r["counted"]:
            # a limit that cut fragments is also named in the frame's warnings (early
            # termination is the threshold working as configured, not a warning)
            assert r["warnings"], r


def test_limits_fire_past_their_bound(sweep):
    deep = {r["config"]: r for r in sweep["rows"] if r["layers"] == 12}
    shallow = {r["config"]: r for r in sweep["rows"] if r["layers"] == 2}
    for label in ("kbuffer k=4 merge", "post_sort max_fragments=8", "depth_peeling max_passes=6"):
        assert shallow[label]["counted"] == 0 and deep[label]["counted"] > 0, label
    assert deep["unsorted_blend"]["rmse_255"] > 5.0
    et = deep["presort_lf_et threshold=0.9"]
    assert et["counted"] > 0 and et["max_255"] <= (1 - 0.9) * 255 + EXACT_255, et


def test_table_lists_counters(sweep):
    md = breaking_points.table(sweep)
    assert "[truncated " in md and "[overflow " in md and md.count("\n|") >= len(breaking_points.CONFIGS) + 1
