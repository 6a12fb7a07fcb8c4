"""Notebooks: a frame shows itself as PNG; the jupyter_rfb widget orbits, pans, zooms and switches
methods from the browser's events, headless (no kernel, no browser)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from guaca_py.notebook import InteractiveView
from guaca_py.scene.loader import demo_scene

W, H = 96, 72


def _event(kind: str, **fields) -> dict:
    """A jupyter_rfb event as the browser sends it (new-style keys)."""
    return {"type": kind, "timestamp": 0.0, "modifiers": (), **fields}


def test_frame_repr_png_is_the_image(renderer_factory):
    frame = renderer_factory("default").render(demo_scene(), W, H)
    png = frame._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    decoded = np.asarray(Image.open(io.BytesIO(png)))
    assert decoded.shape == (H, W, 3) and frame.image.std() > 10
    np.testing.assert_array_equal(decoded, frame.image)


def test_frame_repr_png_reads_a_frame_left_on_the_gpu(renderer_factory):
    r = renderer_factory("default")
    frame = r.render(demo_scene(), W, H, read_back=False)
    assert not frame.is_read
    decoded = np.asarray(Image.open(io.BytesIO(frame._repr_png_())))
    np.testing.assert_array_equal(decoded, r.render(demo_scene(), W, H).image)


@pytest.fixture
def view(renderer_factory):
    v = InteractiveView(demo_scene(), renderer=renderer_factory("default"), size=(W, H))
    yield v
    v.release()


def test_drag_orbits_wheel_zooms_and_the_frame_follows(view):
    first = view.draw()
    assert first.shape == (H, W, 3)
    yaw, distance = view.controller.yaw, view.controller.distance
    assert not view.handle_event(_event("pointer_down", x=10, y=10, button=1, buttons=(1,)))
    assert view.handle_event(_event("pointer_move", x=50, y=14, button=1, buttons=(1,)))
    assert view.controller.yaw == pytest.approx(yaw - 40 * view.controller.ORBIT_SPEED)
    orbited = view.draw()
    assert np.abs(orbited.astype(int) - first).max() > 50
    assert not view.handle_event(_event("pointer_up", x=50, y=14, button=1, buttons=()))
    assert not view.handle_event(_event("pointer_move", x=90, y=14, button=0, buttons=()))  # no button: no drag
    assert view.controller.yaw == pytest.approx(yaw - 40 * view.controller.ORBIT_SPEED)
    assert view.handle_event(_event("wheel", x=5, y=5, dx=0.0, dy=-200.0))  # wheel up: two steps closer
    assert view.controller.distance == pytest.approx(distance * 0.9**2)
    assert np.abs(view.draw().astype(int) - orbited).max() > 50


def test_shift_drag_pans_and_keys_fit_and_reset(view):
    cam = view.scene.camera
    target = view.controller.target.copy()
    view.handle_event(_event("pointer_down", x=10, y=10, button=1, buttons=(1,), modifiers=("Shift",)))
    view.handle_event(_event("pointer_move", x=30, y=10, button=1, buttons=(1,), modifiers=("Shift",)))
    assert np.linalg.norm(view.controller.target - target) > 0  # slid sideways
    assert view.controller.camera().fov_y == cam.fov_y
    assert view.handle_event(_event("key_down", key="c"))  # fit: the scene's centre becomes the target
    lo, hi = view.controller.bounds
    np.testing.assert_allclose(view.controller.target, (lo + hi) / 2)
    assert view.handle_event(_event("key_down", key="r"))
    assert view.controller.camera() is cam  # reset: exactly the scene's camera again
    np.testing.assert_array_equal(view.draw(), view.renderer.render(demo_scene(), W, H).image)
    assert view.handle_event(_event("key_down", key="w"))  # one step forward
    assert np.linalg.norm(view.controller.target - np.asarray(cam.target)) == pytest.approx(view.controller.speed * 0.1)
    assert not view.handle_event(_event("key_down", key="x"))  # no such key: nothing to draw


def test_keys_switch_the_method_and_resize_sets_the_frame_size(view):
    methods = view.methods()
    first = view.method
    assert len(methods) > 3 and first in methods
    assert view.handle_event(_event("key_down", key="m"))
    assert view.method == methods[(methods.index(first) + 1) % len(methods)]
    view.draw()
    assert view.last_stats["method"] == view.method  # the frame was rendered with it
    assert view.handle_event(_event("key_down", key="N"))
    assert view.method == first
    event = _event("resize", width=60.0, height=40.0, pwidth=120, pheight=80, ratio=2.0)
    assert view.handle_event(event)
    assert view.draw().shape == (80, 120, 3)  # physical pixels
    assert view.logical_height == 40  # pointer motion is in logical pixels


def test_widget_headless():
    pytest.importorskip("jupyter_rfb")
    from guaca_py.notebook import GuacaWidget, widget

    w = widget(demo_scene(), width=W, height=H, method="post_sort")
    try:
        assert isinstance(w, GuacaWidget)
        assert w.css_width == f"{W}px" and w.interaction.renderer.owns_context  # its own headless context
        first = w.get_frame()
        assert first.shape == (H, W, 3) and first.std() > 10
        assert w.title == "post_sort"
        # browser events arrive through jupyter_rfb's message handler, as from a kernel
        w._rfb_handle_msg(w, _event("pointer_down", x=10, y=10, button=1, buttons=[1]), [])
        w._rfb_handle_msg(w, _event("pointer_move", x=60, y=30, button=1, buttons=[1]), [])
        assert w._rfb_draw_requested  # the widget asked jupyter_rfb for a new frame
        moved = w.get_frame()
        assert np.abs(moved.astype(int) - first).max() > 50
        picker = w.method_picker()
        assert picker.value == "post_sort" and set(picker.options) == set(w.interaction.methods())
        picker.value = "presort_lf"
        assert w.interaction.method == "presort_lf"
        w.get_frame()
        assert w.interaction.last_stats["method"] == "presort_lf" and w.title == "presort_lf"
        w._rfb_handle_msg(w, _event("key_down", key="m"), [])
        assert picker.value == w.interaction.method != "presort_lf"  # the dropdown follows the key
    finally:
        w.close()
