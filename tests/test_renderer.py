"""Renderer.render_views: several cameras in one call, each view its own image and statistics, shared storage."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import quad_node, simple_scene

import guaca_py.renderer as renderer_module
from guaca_py.errors import ArgumentError, ConfigError, GuacaError
from guaca_py.scene import Camera, stereo_pair

SIZE = 64


def layers(count: int = 6, size: float = 3.0):
    """`count` overlapping half-transparent quads in front of the scene camera, a different colour each."""
    colours = [(1, 0.2, 0.1), (0.1, 0.8, 0.2), (0.2, 0.3, 1), (1, 1, 0.2), (0.8, 0.2, 0.9), (0.2, 0.9, 0.9)]
    return simple_scene([quad_node(f"q{i}", -0.3 * i, colours[i % len(colours)], 0.5, size=size) for i in range(count)])


def cameras() -> list[Camera]:
    """A stereo pair of the scene camera, a camera from the side, and one looking away from everything."""
    cam = layers().camera
    return [
        *stereo_pair(cam, 0.6),
        Camera(position=(2.5, 1, 4), target=(0, 0, -0.5), fov_y=50),
        Camera(position=(0, 0, 5), target=(0, 0, 10), fov_y=50),  # nothing in view
    ]


@pytest.mark.parametrize("read_back", [True, False])
def test_each_view_is_the_frame_render_makes_with_its_camera(renderer_factory, read_back):
    r = renderer_factory("default", method="presort_lf_et")
    scene, cams = layers(), cameras()
    views = r.render_views(scene, cams, SIZE, SIZE, read_back=read_back)
    assert len(views) == len(cams)
    assert len({id(v.texture) for v in views}) == len(cams)  # each view keeps an image of its own
    images = [v.image for v in views]  # read now, before the renders below reuse the textures
    for i, (cam, view, image) in enumerate(zip(cams, views, images)):
        alone = r.render(replace(scene, camera=cam), SIZE, SIZE)
        assert int(np.abs(image.astype(int) - alone.image.astype(int)).max()) <= 1, f"view {i}"
        assert view.stats["view"] == {"index": i, "views": len(cams)}
        if read_back:  # the counters of this view, not of the one before it
            assert view.stats["fragments"]["stored"] == alone.stats["fragments"]["stored"]
    assert not np.array_equal(images[0], images[1])  # the eyes see the layers from two places
    assert "view" not in r.render(scene, SIZE, SIZE).stats  # a plain render() is no view of a set


def counts(frame) -> tuple[int, int | None]:
    """Fragments stored, and the triangles the compute rasterizer found visible (None where it drew none)."""
    compute = frame.stats.get("raster", {}).get("compute")
    return frame.stats["fragments"]["stored"], compute["visible_triangles"] if compute else None


@pytest.mark.parametrize(
    "method, raster",
    [
        ("presort_lf_et", "hardware"),
        ("presort_lf_et", "compute"),
        ("kbuffer", "hardware"),
        ("unsorted_blend", "hardware"),
    ],
)
def test_views_without_read_back_report_their_own_counts_of_the_previous_call(renderer_factory, method, raster):
    # counters (A-buffer, k-buffer, compute rasterizer) and sample counts (blending) read a frame
    # late are kept per view
    r = renderer_factory("default", method=method, method_overrides={"raster": raster})
    scene, cams = layers(), cameras()
    expected = [counts(v) for v in r.render_views(scene, cams, SIZE, SIZE)]
    assert len(set(expected)) > 1 and expected[-1][0] == 0  # the views' counts differ
    assert (expected[0][1] is not None) == (raster == "compute")
    for _ in range(3):
        views = r.render_views(scene, cams, SIZE, SIZE, read_back=False)
    assert [counts(v) for v in views] == expected
    assert all(v.stats.get("fragments_of") == "previous frame" for v in views)
    assert not any(v.is_read for v in views)


def test_views_build_the_draw_list_once_and_upload_nothing_again(renderer_factory, monkeypatch):
    r = renderer_factory("default", method="presort_lf_et")
    scene, cams = layers(), cameras()
    r.render_views(scene, cams, SIZE, SIZE)
    built = []
    real = renderer_module.build_draw_list
    monkeypatch.setattr(renderer_module, "build_draw_list", lambda *a, **k: built.append(1) or real(*a, **k))
    uploads, serial = r.meshes.uploads, r.frame_serial
    r.render_views(scene, cams, SIZE, SIZE, read_back=False, stats=False)
    assert len(built) == 1
    assert r.meshes.uploads == uploads
    assert r.frame_serial == serial + 1  # one call: every view's texture valid until the next


POOLS = {
    "presort_lf_et": lambda m: (m.capacity, m._nodes.glo),
    "paged_ll": lambda m: (m.capacity, m._bufs["nodes"].glo),
    "multilayer_depth_peeling": lambda m: (m.storage.capacity, m.storage._nodes.glo),
}


@pytest.mark.parametrize("method", list(POOLS))
@pytest.mark.parametrize("read_back", [True, False])
def test_views_share_one_pool_sized_for_the_largest(renderer_factory, monkeypatch, method, read_back):
    # a deep view and a shallow one: a pool shrunk after the shallow view would be made again
    # (and overflow) at the deep one, every call; it holds the deep view's need instead
    r = renderer_factory("default", method=method)
    scene = layers(count=12, size=20.0)  # 12 full-screen layers: several times the first pool
    cams = [scene.camera, Camera(position=(10, 10, -3), target=(10, 10, -10), fov_y=50)]  # a corner of the last layer
    pools = []
    real = r.method.prepare

    def prepare(frame):
        real(frame)
        pools.append(POOLS[method](r.method))

    monkeypatch.setattr(r.method, "prepare", prepare)
    for _ in range(3):  # the first call grows the pool to the deep view's need
        views = r.render_views(scene, cams, SIZE, SIZE, read_back=read_back)
    first = pools.index(pools[-1])
    assert set(pools[first:]) == {pools[-1]}  # the same pool since, at every view
    assert first <= len(pools) - 4  # over two whole calls at least
    allocated = [{k: b for k, b in v.stats["memory"].items() if not k.endswith("_used")} for v in views]
    assert allocated[0] == allocated[1]
    stored = [v.stats["fragments"]["stored"] for v in views]
    assert stored[0] > 4 * stored[1] > 0
    assert not any("overflow" in w for v in views for w in v.stats.get("warnings", []))


def test_view_textures_expire_with_the_next_call(renderer_factory):
    r = renderer_factory("default", method="presort_lf_et")
    views = r.render_views(layers(), cameras()[:2], SIZE, SIZE, read_back=False)
    r.render(layers(), SIZE, SIZE)
    with pytest.raises(GuacaError, match="reused by a later render"):
        views[0].read()


@pytest.mark.parametrize(
    "value, error, match",
    [
        ([], ConfigError, r"'cameras': must hold at least one Camera"),
        (Camera(), ArgumentError, r"'cameras': must be a sequence of Cameras, got Camera"),
        ("left", ArgumentError, r"'cameras': must be a sequence of Cameras, got str"),
        (5, ArgumentError, r"'cameras': must be a sequence of Cameras, got int"),
        ([Camera(), "right"], ArgumentError, r"'cameras\[1\]': must be a Camera, got str"),
        ([Camera(), Camera(position=(0, math.nan, 5))], ConfigError, r"'cameras\[1\]\.position': must be 3 finite"),
        ([Camera(fov_y=0)], ConfigError, r"'cameras\[0\]\.fov_y'"),
        ([Camera(position=(0, 0, 0), target=(0, 0, 0))], ConfigError, r"'cameras\[0\]\.target': must differ"),
    ],
)
def test_render_views_refuses_what_is_no_list_of_cameras(renderer_factory, value, error, match):
    r = renderer_factory("default", method="presort_lf_et")
    serial = r.frame_serial
    with pytest.raises(error, match=match):
        r.render_views(layers(), value, SIZE, SIZE)
    assert r.frame_serial == serial  # refused before any work
