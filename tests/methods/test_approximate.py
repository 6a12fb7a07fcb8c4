"""Approximate methods measured against the float64 reference, with each method's exact special case asserted."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import quad_node, simple_scene

from guaca_py.errors import ConfigError
from guaca_py.reference import compare, interpenetrating_scene, layered_quads_scene
from guaca_py.reference import reference_of as cpu_reference
from guaca_py.scene.graph import Light, MaterialInstance

SIZE = 96
EXACT_255 = 2.0
SCENES = {
    "front_to_back": lambda: layered_quads_scene(n_layers=12, order="front_to_back", seed=3),
    "back_to_front": lambda: layered_quads_scene(n_layers=12, order="back_to_front", seed=3),
    "shuffled": lambda: layered_quads_scene(n_layers=12, order="shuffled", seed=3),
    "interpenetrating": lambda: interpenetrating_scene(order="forward"),
}
# (label, method id, settings): every approximate method, plus the variants the checks need
CONFIGS = [
    ("unsorted_blend", "unsorted_blend", {}),
    ("object_sorted_blend", "object_sorted_blend", {}),
    ("kbuffer k=16", "kbuffer", {"k": 16}),
    ("kbuffer k=2 merge", "kbuffer", {"k": 2, "overflow": "merge"}),
    ("kbuffer k=2 drop", "kbuffer", {"k": 2, "overflow": "drop"}),
    ("weighted_blended eq7", "weighted_blended", {}),
    ("weighted_blended eq10 16f", "weighted_blended", {"weight": "eq10", "accum_format": "rgba16f"}),
    ("stochastic S=4", "stochastic", {"samples": 4}),
    ("stochastic S=16", "stochastic", {"samples": 16}),
    ("stochastic S=8 raw", "stochastic", {"samples": 8, "alpha_correction": False}),
]


def reference_of(scene, w=SIZE, h=SIZE):
    """Reference image, edge exclusion mask and per-pixel layer counts at this module's size."""
    return cpu_reference(scene, w, h)


@pytest.fixture(scope="module")
def references():
    return {name: (build(), *reference_of(build())) for name, build in SCENES.items()}


@pytest.fixture(scope="module")
def measurements(renderer_factory, references):
    """Every configuration on every scene: error (1/255) and the frame's stats."""
    out = {}
    for label, mid, settings in CONFIGS:
        r = renderer_factory("exact", method=mid, method_overrides=settings)
        for name, (scene, ref, mask, _layers) in references.items():
            frame = r.render(scene, SIZE, SIZE)
            err = compare(frame.image, ref, mask)
            out[(label, name)] = {
                "rmse_255": err["rmse_255"],
                "max_255": err["max_abs_255"],
                "stats": json.loads(json.dumps(frame.stats)),
            }
    return out


def test_error_table_written_and_finite(measurements, references, tmp_path_factory, capsys):
    path = tmp_path_factory.mktemp("approx") / "approximate_errors.json"
    rows = [
        {
            "config": label,
            "scene": name,
            "rmse_255": m["rmse_255"],
            "max_255": m["max_255"],
            "fragments": m["stats"]["fragments"],
            "memory": m["stats"]["memory"],
            "geometry_passes": m["stats"]["geometry_passes"],
        }
        for (label, name), m in measurements.items()
    ]
    path.write_text(json.dumps({"size": SIZE, "unit": "1/255, non-edge pixels", "rows": rows}, indent=2))
    assert json.loads(path.read_text())["rows"]
    names = list(SCENES)
    lines = [
        f"approximate methods vs float64 reference, {SIZE}x{SIZE}, RMSE / max in 1/255 ({path})",
        f"{'config':<28}" + "".join(f"{n:>20}" for n in names),
    ]
    for label, _, _ in CONFIGS:
        lines.append(
            f"{label:<28}"
            + "".join(
                f"{measurements[(label, n)]['rmse_255']:>11.2f} /{measurements[(label, n)]['max_255']:>6.1f}"
                for n in names
            )
        )
    with capsys.disabled():
        print("\n" + "\n".join(lines))
    for row in rows:
        assert math.isfinite(row["rmse_255"]) and math.isfinite(row["max_255"]), row
        assert row["max_255"] <= 255.0


def test_unsorted_blend_exact_only_for_back_to_front(measurements):
    assert measurements[("unsorted_blend", "back_to_front")]["max_255"] <= EXACT_255
    # the other submission orders blend out of order: the error must show
    assert measurements[("unsorted_blend", "front_to_back")]["max_255"] > 20
    assert measurements[("unsorted_blend", "shuffled")]["max_255"] > 20


def test_object_sorted_blend_exact_in_any_order(measurements):
    for order in ("front_to_back", "back_to_front", "shuffled"):
        assert measurements[("object_sorted_blend", order)]["max_255"] <= EXACT_255, order
    # per-object order cannot resolve triangles that cut through each other
    assert measurements[("object_sorted_blend", "interpenetrating")]["max_255"] > 10


def test_kbuffer_exact_when_k_covers_depth_complexity(measurements, references):
    for name, (_, _, _, layers) in references.items():
        assert layers.max() <= 16
        m = measurements[("kbuffer k=16", name)]
        assert m["max_255"] <= EXACT_255, (name, m)
        fr = m["stats"]["fragments"]
        assert fr["overflow"] == 0 and fr["dropped"] == 0 and fr["stored"] == fr["total"] > 0
    assert references["shuffled"][3].max() > 2
    # k below the depth complexity: overflow is counted and reported, and the image is measurably off
    for label in ("kbuffer k=2 merge", "kbuffer k=2 drop"):
        m = measurements[(label, "shuffled")]
        fr = m["stats"]["fragments"]
        # deepest pixel: transparent fragments in front of the opaque (reference layers count all hits)
        assert fr["overflow"] > 0 and 2 < fr["max_per_pixel_over_k"] <= references["shuffled"][3].max(), fr
        assert any("k-buffer overflow" in w for w in m["stats"]["warnings"])
        assert m["max_255"] > 10, (label, m)
    assert measurements[("kbuffer k=2 merge", "shuffled")]["stats"]["fragments"]["merged"] > 0
    # dropping loses the far layers entirely; merging keeps their contribution approximately
    assert (
        measurements[("kbuffer k=2 merge", "shuffled")]["rmse_255"]
        < measurements[("kbuffer k=2 drop", "shuffled")]["rmse_255"]
    )
    # memory is bounded by k, whatever the depth complexity
    mem = measurements[("kbuffer k=2 drop", "shuffled")]["stats"]["memory"]
    assert mem["kbuffer_slots"] == SIZE * SIZE * 2 * mem["kbuffer_node_bytes"]
    assert mem["kbuffer_slots_used"] <= mem["kbuffer_slots"]


def test_weighted_blended_measured_inexact_on_layers(measurements):
    # order independent by construction: one image for every submission order, not the exact one
    imgs = [
        measurements[("weighted_blended eq7", o)]["rmse_255"] for o in ("front_to_back", "back_to_front", "shuffled")
    ]
    assert max(imgs) - min(imgs) < 0.05 and min(imgs) > 1.0


@pytest.mark.parametrize("settings", [{}, {"weight": "eq10", "accum_format": "rgba16f"}, {"weight": "eq8"}])
def test_weighted_blended_single_layer_and_equal_colors_exact(renderer_factory, settings):
    r = renderer_factory("exact", method="weighted_blended", method_overrides=settings)
    single = simple_scene(
        [
            quad_node("op", -1.0, (0.9, 0.8, 0.2), 1.0, size=1.5, xy=(0.4, 0.0)),
            quad_node("t", 0.5, (0.2, 0.5, 0.9), 0.45, size=2.5),
        ]
    )
    ref, mask, _ = reference_of(single, 64, 64)
    assert compare(r.render(single, 64, 64).image, ref, mask)["max_abs_255"] <= EXACT_255
    # equal colors: the weighted average color is that color and the coverage is exact
    same = (0.7, 0.3, 0.5)
    nodes = [
        quad_node(f"q{i}", 1.5 - 0.6 * i, same, a, size=s, xy=(0.2 * i - 0.4, 0.1 * i))
        for i, (a, s) in enumerate([(0.3, 2.6), (0.55, 1.8), (0.2, 3.0), (0.7, 1.2), (0.4, 2.2)])
    ]
    nodes.insert(2, quad_node("op", 0.0, (0.1, 0.9, 0.2), 1.0, size=1.0, xy=(0.5, -0.5)))
    scene = simple_scene(nodes)
    ref, mask, layers = reference_of(scene, 64, 64)
    assert layers.max() >= 4
    assert compare(r.render(scene, 64, 64).image, ref, mask)["max_abs_255"] <= EXACT_255


def test_stochastic_error_falls_with_samples(renderer_factory, references):
    scene, ref, mask, _ = references["shuffled"]
    rmse = {}
    for s in (4, 16):
        runs = [
            compare(
                renderer_factory("exact", method="stochastic", method_overrides={"samples": s, "seed": seed})
                .render(scene, SIZE, SIZE)
                .image,
                ref,
                mask,
            )["rmse_255"]
            for seed in range(3)
        ]
        rmse[s] = float(np.mean(runs))
    # Monte-Carlo noise ~ 1/sqrt(S): four times the samples should about halve the error
    assert rmse[16] < 0.75 * rmse[4], rmse


def test_stochastic_reproducible_per_seed(renderer_factory, references):
    scene = references["shuffled"][0]
    a = renderer_factory("exact", method="stochastic", method_overrides={"seed": 5}).render(scene, 64, 64).image
    b = renderer_factory("exact", method="stochastic", method_overrides={"seed": 5}).render(scene, 64, 64).image
    c = renderer_factory("exact", method="stochastic", method_overrides={"seed": 6}).render(scene, 64, 64).image
    assert (a == b).all() and (a != c).any()


def test_stochastic_alpha_correction_helps(measurements):
    for name in ("shuffled", "interpenetrating"):
        assert (
            measurements[("stochastic S=8 raw", name)]["rmse_255"] > measurements[("stochastic S=16", name)]["rmse_255"]
        )


@pytest.mark.parametrize("label", [c[0] for c in CONFIGS])
def test_stats_reported(measurements, label):
    s = measurements[(label, "shuffled")]["stats"]
    fr = s["fragments"]
    assert {"stored", "dropped", "merged"} <= set(fr) and fr["stored"] > 0
    mem = s["memory"]
    alloc = [k for k in mem if k != "gbuffer" and k != "lights" and not k.endswith(("_used", "node_bytes"))]
    assert alloc and all(f"{k}_used" in mem for k in alloc), mem
    assert s["geometry_passes"] == (2 if label.startswith("stochastic") else 1)


def test_object_sorted_order_is_back_to_front(renderer_factory):
    from guaca_py.methods.approximate import world_bbox_centre
    from guaca_py.pipeline.drawlist import build_draw_list
    from guaca_py.pipeline.frame import FrameContext

    scene = layered_quads_scene(n_layers=8, order="shuffled", seed=1, with_opaque=False)
    r = renderer_factory("exact", method="object_sorted_blend")
    draws = build_draw_list(scene, r.materials)
    view, proj = scene.camera.view_matrix(), scene.camera.projection_matrix(1.0)
    frame = FrameContext(r.device, r.method, r.raster, scene, 32, 32, draws, view, proj)
    order = r.method.draw_order(frame)
    assert sorted(d.index for d in order) == sorted(d.index for d in draws)
    dist = [np.linalg.norm(world_bbox_centre(d) - frame.camera_position) for d in order]
    assert dist == sorted(dist, reverse=True)
    assert [d.name for d in order] == sorted((d.name for d in draws), reverse=True)  # layer00 nearest: drawn last


def test_lit_fragments_shaded_like_the_composite(renderer_factory):
    # one lit transparent layer over a lit opaque one: in-place shading (forward methods) and
    # stored-then-composited shading (k-buffer) must both match the exact A-buffer path
    def pbr(albedo, alpha):
        return MaterialInstance("pbr", {"albedo": list(albedo), "alpha": alpha, "roughness": 0.4})

    op = quad_node("op", -1.0, (0, 0, 0), 1.0, size=3.0)
    op.material = pbr((0.8, 0.7, 0.6), 1.0)
    tr = quad_node("tr", 0.5, (0, 0, 0), 1.0, size=2.0, rot=(20.0, -15.0, 0.0))
    tr.material = pbr((0.2, 0.4, 0.9), 0.5)
    scene = simple_scene([op, tr])
    scene.lights = [Light(type="point", position=(0.5, 1.0, 2.5), color=(1.0, 0.9, 0.8), intensity=6.0, radius=12.0)]
    exact = renderer_factory("exact", method="presort_lf").render(scene, 64, 64).linear
    assert exact.std() > 0.02  # lighting varies over the image
    for mid, settings in [
        ("unsorted_blend", {}),
        ("object_sorted_blend", {}),
        ("weighted_blended", {}),
        ("stochastic", {"samples": 8}),
        ("kbuffer", {"k": 4}),
    ]:
        lin = renderer_factory("exact", method=mid, method_overrides=settings).render(scene, 64, 64).linear
        err = np.abs(np.clip(lin, 0, 1) - np.clip(exact, 0, 1)) * 255.0
        assert np.percentile(err, 99) <= EXACT_255, (mid, float(err.max()))


@pytest.mark.parametrize(
    "mid,settings",
    [
        ("stochastic", {"samples": 33}),
        ("kbuffer", {"overflow": "keep"}),
        ("kbuffer", {"k": 0}),
        ("weighted_blended", {"weight": "eq11"}),
        ("weighted_blended", {"accum_format": "rgba8"}),
    ],
)
def test_bad_settings_rejected(renderer_factory, mid, settings):
    with pytest.raises(ConfigError):
        renderer_factory("exact", method=mid, method_overrides=settings)


def test_kbuffer_interlock_needs_the_extension(renderer_factory, gl_context):
    from guaca_py import UnsupportedMethodError
    from guaca_py.context import detect_capabilities

    caps = detect_capabilities(gl_context)
    if caps.fragment_interlock:
        r = renderer_factory("exact", method="kbuffer", method_overrides={"lock": "interlock"})
        assert r.method.lock == "interlock" and "interlock" in r.method.extensions()
    else:
        with pytest.raises(UnsupportedMethodError, match="interlock"):
            renderer_factory("exact", method="kbuffer", method_overrides={"lock": "interlock"})
        assert renderer_factory("exact", method="kbuffer").method.lock == "spin"
