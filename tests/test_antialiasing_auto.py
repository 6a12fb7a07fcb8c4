"""antialiasing: auto: 4 coverage samples or supersample 2 per frame, from what the previous frame measured."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_quads

from guaca_py.antialiasing import with_samples, with_settings, with_supersample
from guaca_py.antialiasing_auto import (
    HYSTERESIS,
    NORMAL_TURN_MAX,
    choose,
    coverage_cost,
    supersample_cost,
)
from guaca_py.errors import ConfigError
from guaca_py.pipeline.config import load_pipeline, pipeline_from_text
from guaca_py.reference import origin_camera, unlit
from guaca_py.scene.graph import MeshData, Node, Scene, Transform

EXACT = load_pipeline("exact")
AUTO = with_settings(EXACT, "auto", "test")


def crossing() -> float:
    """The mean triangle area (px²) at which both estimates are equal (bisection: coverage falls, supersampling rises)."""
    lo, hi = 0.01, 100.0
    for _ in range(60):
        mid = (lo * hi) ** 0.5
        lo, hi = (mid, hi) if supersample_cost(mid) < coverage_cost(mid) else (lo, mid)
    return lo


def measured(area: float, fragments: int = 1000, pixels: int = 1024 * 1024) -> dict:
    return {"transparent_draws": 3, "mean_triangle_area_px": area, "fragments_1x": fragments, "output_pixels": pixels}


GIB = 1 << 30


@pytest.fixture(scope="module")
def pool(gl_context):
    """A presort_lf_et method on this device with its buffers capped at 1 GiB (its pool's own sizing rule)."""
    import dataclasses

    from guaca_py.context import detect_capabilities
    from guaca_py.methods import method_class
    from guaca_py.renderer import method_settings

    caps = detect_capabilities(gl_context)
    caps = dataclasses.replace(caps, limits=dataclasses.replace(caps.limits, max_buffer_bytes=GIB))
    return method_class("presort_lf_et")(method_settings("presort_lf_et", {}), caps)


def test_auto_switches_where_the_estimates_cross():
    """Fed the previous frame's stats: supersample 2 below the crossing area, 4 samples above, with hysteresis."""
    x = crossing()
    assert 0.2 < x < 5.0  # small triangles, relative to a pixel
    assert choose(None, None, None, None) == ("samples", "the first frame renders with 4 samples")
    mode, why = choose(measured(x / 4), "samples", None, None)
    assert mode == "supersample" and "estimated cost" in why and "px²" in why
    assert choose(measured(x * 4), "supersample", None, None)[0] == "samples"
    # just past the crossing the previous frame's mode stays (within HYSTERESIS of the other's estimate)
    near_below, near_above = x * 0.97, x * 1.03
    assert supersample_cost(near_below) > (1 - HYSTERESIS) * coverage_cost(near_below)
    assert choose(measured(near_below), "samples", None, None)[0] == "samples"
    assert choose(measured(near_above), "supersample", None, None)[0] == "supersample"
    assert choose(measured(near_below), "supersample", None, None)[0] == "supersample"
    assert choose(measured(near_above), "samples", None, None)[0] == "samples"


def test_auto_keeps_samples_where_supersampling_would_not_fit_or_has_nothing_to_do(pool):
    """Four times the 1-sample fragments must fit the method's pool at four times the pixels (the pool's own rule:
    payloads in one buffer, heads and links in another); a frame without transparency takes 4 samples; a method
    without coverage masks always supersamples."""
    tiny = crossing() / 4
    # 1 GiB of 32-byte payloads: 2**25 nodes, node 0 the null link; at 1 Mpx the links' buffer holds more
    room = GIB // 32 - 1
    top = room // 4
    assert top * 4 * 40 > GIB  # a 40-bytes-a-node estimate against one buffer refused this; it fits
    assert choose(measured(tiny, top), "samples", None, pool.pool_fragments)[0] == "supersample"
    mode, why = choose(measured(tiny, top + 1), "samples", None, pool.pool_fragments)
    assert mode == "samples" and f"would store {4 * (top + 1):,} fragments, over the {room:,}" in why
    # a frame so large that the heads leave the links' buffer room for 2**24 nodes: that buffer binds
    pixels = (GIB // pool.link_bytes - (1 << 24)) // 4
    top = ((1 << 24) - 1) // 4
    assert choose(measured(tiny, top, pixels), "samples", None, pool.pool_fragments)[0] == "supersample"
    assert choose(measured(tiny, top + 1, pixels), "samples", None, pool.pool_fragments)[0] == "samples"
    assert choose({**measured(tiny), "transparent_draws": 0}, "samples", None, None)[0] == "samples"
    assert choose(measured(1000.0), "samples", "method 'dfb' carries no coverage masks", None) == (
        "supersample",
        "method 'dfb' carries no coverage masks",
    )


def fine_grid(n: int, half: float = 1.2) -> MeshData:
    """A square of n x n quads (2 n² triangles) in the XY plane: many triangles smaller than a pixel."""
    xs = np.linspace(-half, half, n + 1, dtype=np.float32)
    gx, gy = np.meshgrid(xs, xs)
    pos = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size, np.float32)], axis=1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i.ravel(), i.ravel() + 1, i.ravel() + n + 2, i.ravel() + n + 1
    idx = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.uint32)
    return MeshData(
        positions=pos,
        normals=np.tile(np.float32([0, 0, 1]), (len(pos), 1)),
        texcoords=(pos[:, :2] / (2 * half) + 0.5).astype(np.float32),
        indices=idx,
        name=f"grid{n}",
    )


def tiny_triangle_scene() -> Scene:
    """Two tilted, interpenetrating transparent grids of sub-pixel triangles at 32²."""
    nodes = [
        Node("a", Transform((0.0, 0.0, 0.0), (0.0, 30.0, 10.0)), fine_grid(48), unlit((0.9, 0.3, 0.1), 0.5)),
        Node("b", Transform((0.2, -0.1, 0.0), (25.0, -20.0, 0.0)), fine_grid(48), unlit((0.1, 0.5, 0.9), 0.6)),
    ]
    return Scene(camera=origin_camera(), background=(0.05, 0.08, 0.12), nodes=nodes)


def test_auto_renders_what_the_chosen_mode_renders(renderer_factory):
    """Frame by frame, auto's image is that of the mode it chose: 4 samples first, supersample 2 once the previous
    frame measured sub-pixel triangles, 4 samples again on large ones (after the hysteresis)."""
    r = renderer_factory(AUTO)
    samples = renderer_factory(with_samples(EXACT, 4))
    supersampled = renderer_factory(with_supersample(EXACT, 2))
    tiny, large = tiny_triangle_scene(), random_quads(1)
    size = 32
    first = r.render(tiny, size, size)
    assert first.stats["antialiasing"]["auto"]["chose"] == "samples 4"
    np.testing.assert_array_equal(first.linear, samples.render(tiny, size, size).linear)
    second = r.render(tiny, size, size)
    auto = second.stats["antialiasing"]["auto"]
    assert auto["chose"] == "supersample 2", auto
    assert auto["previous_frame"]["mean_triangle_area_px"] < crossing()
    assert second.stats["render_resolution"] == [2 * size, 2 * size] and second.stats["antialiasing"]["samples"] == 1
    np.testing.assert_array_equal(second.linear, supersampled.render(tiny, size, size).linear)
    r.render(large, size, size)  # measured on large triangles: the next frame goes back to 4 samples
    back = r.render(large, size, size)
    assert back.stats["antialiasing"]["auto"]["chose"] == "samples 4"
    np.testing.assert_array_equal(back.linear, samples.render(large, size, size).linear)


def test_auto_with_a_method_without_coverage_supersamples(renderer_factory):
    """A method that refuses samples > 1 is not refused under auto: every frame is supersampled."""
    r = renderer_factory(AUTO, method="dfb")
    scene = random_quads(2, n=4)
    frame = r.render(scene, 24, 24)
    assert frame.stats["antialiasing"]["auto"]["chose"] == "supersample 2"
    assert "'dfb' carries no coverage masks" in frame.stats["antialiasing"]["auto"]["why"]
    expected = renderer_factory(with_supersample(EXACT, 2), method="dfb").render(scene, 24, 24)
    np.testing.assert_array_equal(frame.linear, expected.linear)


def test_auto_setting_parsed_and_overridden():
    """`antialiasing: auto` is {auto: true}; with samples or supersample beside it, refused with its line; a later
    samples or supersample (an argument, a --set) turns it off, a later auto turns them off."""
    text = "antialiasing: auto\npasses: [geometry, light_culling, composite]\n"
    assert pipeline_from_text(text, "p.yaml").antialiasing == {"samples": 1, "supersample": 1, "auto": True}
    with pytest.raises(ConfigError, match=r"p.yaml:1: 'antialiasing.auto': chooses samples and supersample"):
        pipeline_from_text(
            "antialiasing: {auto: true, samples: 4}\npasses: [geometry, light_culling, composite]\n", "p.yaml"
        )
    assert with_samples(AUTO, 4).antialiasing == {"samples": 4, "supersample": 1, "auto": False}
    assert with_settings(with_supersample(EXACT, 3), "auto", "t").antialiasing["supersample"] == 1


def test_auto_supersamples_where_normals_turn_within_a_pixel():
    """The edge-quality rule: where normals turn faster than NORMAL_TURN_MAX per pixel, 4 samples (one shade per
    pixel) fall short of supersample 2's edge error, so auto supersamples even where 4 samples cost less; the
    storage rule still comes first."""
    large = crossing() * 16  # triangles where 4 samples are the cheaper estimate
    assert (
        choose({**measured(large), "normal_turn_per_px": NORMAL_TURN_MAX * 0.5}, "samples", None, None)[0] == "samples"
    )
    mode, why = choose({**measured(large), "normal_turn_per_px": NORMAL_TURN_MAX * 1.5}, "samples", None, None)
    assert mode == "supersample" and "rad per pixel" in why and "estimated cost" in why
    # near the line the previous frame's mode stays (HYSTERESIS, as for the costs)
    near = {**measured(large), "normal_turn_per_px": NORMAL_TURN_MAX * (1 + HYSTERESIS / 2)}
    assert choose(near, "samples", None, None)[0] == "samples"
    assert choose(near, None, None, None)[0] == "supersample"
    near_below = {**measured(large), "normal_turn_per_px": NORMAL_TURN_MAX * (1 - HYSTERESIS / 2)}
    assert choose(near_below, "supersample", None, None)[0] == "supersample"
    assert choose(near_below, "samples", None, None)[0] == "samples"
    too_many = {**measured(large, fragments=10_000_000), "normal_turn_per_px": NORMAL_TURN_MAX * 1.5}
    assert choose(too_many, "samples", None, lambda pixels: 4 * 10_000_000 - 1)[0] == "samples"
    assert choose(too_many, "samples", None, lambda pixels: 4 * 10_000_000)[0] == "supersample"


def test_auto_measures_the_normal_turn_of_the_frame(renderer_factory):
    """A frame's measurement carries the transparent triangles' normal turn: 0 for flat grids, and a grid whose
    normals fan out turns them within each pixel, so the next frame is supersampled."""
    r = renderer_factory(AUTO)
    size = 32
    flat = random_quads(1)
    r.render(flat, size, size)
    frame = r.render(flat, size, size)
    assert frame.stats["antialiasing"]["auto"]["previous_frame"]["normal_turn_per_px"] == 0.0
    assert frame.stats["antialiasing"]["auto"]["chose"] == "samples 4"
    grid = fine_grid(8)
    xy = grid.positions[:, :2]
    # 7 rad per unit: 2.1 rad across a 0.3-unit cell of about 2 px
    fan = np.stack([np.sin(7 * xy[:, 0]), np.zeros(len(xy)), np.cos(7 * xy[:, 0])], axis=1).astype(np.float32)
    bumpy = MeshData(positions=grid.positions, normals=fan, texcoords=grid.texcoords, indices=grid.indices, name="fan")
    scene = Scene(
        camera=origin_camera(), nodes=[Node("fan", Transform((0, 0, 0), (0, 0, 0)), bumpy, unlit((1, 1, 1), 0.5))]
    )
    r.render(scene, size, size)
    frame = r.render(scene, size, size)
    auto = frame.stats["antialiasing"]["auto"]
    assert auto["previous_frame"]["normal_turn_per_px"] > NORMAL_TURN_MAX, auto
    assert auto["chose"] == "supersample 2" and "rad per pixel" in auto["why"]
