"""The viewer: headless runs match `guaca render`, keys switch methods and views, the camera moves."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from guaca_py.cli import main
from guaca_py.scene.graph import Camera

pytest.importorskip("moderngl_window")

W, H = 112, 96
SCENE = """
camera: {position: [0.5, 1.2, 4], target: [0, 0.3, 0], fov_y: 50}
lights:
  - {type: point, position: [1, 3, 2], intensity: 15, radius: 12}
nodes:
  - {name: floor, mesh: {primitive: plane, size: [4, 4]}, material: {description: pbr, uniforms: {albedo: [0.7, 0.7, 0.7]}}}
  - {name: box, mesh: {primitive: box, size: [0.8, 0.8, 0.8]}, transform: {translation: [-0.5, 0.4, 0]},
     material: {description: pbr, uniforms: {albedo: [0.8, 0.2, 0.1]}}}
  - {name: glass, mesh: {primitive: sphere, radius: 0.6}, transform: {translation: [0.4, 0.6, 0.3]},
     material: {description: pbr, uniforms: {albedo: [0.2, 0.5, 0.9], alpha: 0.4}}}
  - {name: pane, mesh: {primitive: quad, size: [1.5, 1.2]}, transform: {translation: [0, 0.6, 1]},
     material: {description: unlit, uniforms: {color: [0.1, 0.9, 0.2], alpha: 0.5}}}
"""


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    p = tmp_path_factory.mktemp("view") / "scene.yaml"
    p.write_text(SCENE)
    return p


@pytest.fixture(scope="module")
def window():
    import moderngl_window as mglw

    wnd = mglw.get_local_window_cls("headless")(size=(W, H), gl_version=(4, 5), backend="egl")
    yield wnd
    wnd.destroy()


def _read(fbo) -> np.ndarray:
    w, h = fbo.size
    return np.frombuffer(fbo.read(components=3), np.uint8).reshape(h, w, 3)[::-1].copy()


@pytest.mark.parametrize("method", ["presort_lf_et", "post_sort"])
def test_headless_view_screenshot_matches_render(scene_file, tmp_path, method, capsys):
    shot, ref = tmp_path / "view.png", tmp_path / "render.png"
    size = ["--width", str(W), "--height", str(H), "--method", method]
    assert main(["view", str(scene_file), "--headless", "--frames", "3", "--screenshot", str(shot), *size]) == 0
    assert "3 frames" in capsys.readouterr().out
    assert main(["render", str(scene_file), "--out", str(ref), *size]) == 0
    a, b = np.asarray(Image.open(shot))[:, :, :3], np.asarray(Image.open(ref))[:, :, :3]
    assert a.shape == b.shape == (H, W, 3)
    assert a.std() > 10  # a real image, not a cleared window
    np.testing.assert_array_equal(a, b)


def test_headless_view_of_a_glb_matches_render(tmp_path):
    from test_gltf import write_test_glb

    glb = write_test_glb(tmp_path / "modes.glb")
    shot, ref = tmp_path / "view.png", tmp_path / "render.png"
    size = ["--width", str(W), "--height", str(H)]
    assert main(["view", str(glb), "--headless", "--frames", "2", "--screenshot", str(shot), *size]) == 0
    assert main(["render", str(glb), "--out", str(ref), *size]) == 0
    a, b = np.asarray(Image.open(shot))[:, :, :3], np.asarray(Image.open(ref))[:, :, :3]
    assert a.std() > 10
    np.testing.assert_array_equal(a, b)


def test_keys_switch_method_view_and_overflow(window, scene_file):
    from guaca_py.scene.loader import load_scene
    from guaca_py.viewer import Viewer

    viewer = Viewer(window.ctx, load_scene(scene_file))
    try:
        window.use()
        viewer.frame(window.fbo)
        shaded = _read(window.fbo)
        first = viewer.method
        viewer.key("M")
        assert viewer.method != first and viewer.method in viewer.runnable_methods()
        viewer.key("N")
        assert viewer.method == first
        viewer.key("2")
        viewer.frame(window.fbo)
        assert viewer.renderer().pass_named("debug_depth_complexity") is not None
        heat = _read(window.fbo)
        rows = slice(H // 2, H)  # below the status line
        assert np.abs(heat[rows].astype(int) - shaded[rows]).max() > 50
        assert viewer.last_stats["passes"].get("debug_depth_complexity") is not None  # timed after a change
        viewer.key("O")
        viewer.frame(window.fbo)
        assert viewer.last_stats["fragments"]["overflow"] > 0
        assert "OVERFLOW" in viewer.status_lines()[1]
        viewer.key("O")
        viewer.key("1")
        viewer.frame(window.fbo)
        assert viewer.last_stats["fragments"]["overflow"] == 0
        # the status line covers the top rows; the rest is guaca's frame, unchanged
        viewer.key("H")
        viewer.frame(window.fbo)
        no_hud = _read(window.fbo)
        assert np.abs(no_hud[:10].astype(int) - shaded[:10]).max() > 30
        below = 14 * len(viewer.status_lines()) + 4  # hud.LINE_HEIGHT per line
        np.testing.assert_array_equal(no_hud[below:], shaded[below:])
    finally:
        viewer.release()


def test_camera_controller_orbit_zoom_fly():
    from guaca_py.viewer import CameraController

    cam = Camera(position=(0.0, 1.0, 5.0), target=(0.0, 0.0, 0.0), fov_y=40)
    c = CameraController(cam)
    assert c.camera() is cam  # untouched: exactly the scene's camera
    np.testing.assert_allclose(c.eye, cam.position, atol=1e-12)
    d0 = c.distance
    c.drag(100, 0)
    moved = c.camera()
    assert np.linalg.norm(np.subtract(moved.position, moved.target)) == pytest.approx(d0)
    assert moved.position[0] != pytest.approx(0.0)
    c.drag(0, 1e6)  # pitch is clamped short of the pole (the up vector stays usable)
    assert abs(c.pitch) < np.pi / 2
    c.zoom(3)
    assert c.distance == pytest.approx(d0 * 0.9**3)
    assert c.toggle_mode() == "fly"
    eye = c.eye.copy()
    c.drag(50, 0)  # fly: turning keeps the eye in place
    np.testing.assert_allclose(c.eye, eye, atol=1e-9)
    target = c.target.copy()
    c.move(1.0, 0.0, 0.0)
    assert np.linalg.norm(c.target - target) == pytest.approx(1.0)
    np.testing.assert_allclose(c.eye - eye, c.target - target, atol=1e-9)
