"""The viewer: headless runs match `guaca render`, keys switch methods and views, the camera moves
(orbit, pan, zoom, fit, held keys by frame time), heat maps fit the frame, the status line says it all."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from guaca_py.cli import main
from guaca_py.passes.debug_views import heat_color, legend_rows
from guaca_py.scene.graph import Camera
from guaca_py.viewer.hud import LINE_HEIGHT

pytest.importorskip("moderngl_window")

W, H = 112, 96
HUD_W, HUD_H = 480, 200  # wide enough for the status line to leave rows of the frame below it
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

    wnd = mglw.get_local_window_cls("headless")(size=(HUD_W, HUD_H), gl_version=(4, 5), backend="egl")
    yield wnd
    wnd.destroy()


class Keys:
    """Key codes for a window whose toolkit has none (headless): each key's code is its name."""

    ACTION_PRESS, ACTION_RELEASE = "press", "release"
    W, P = "W", "P"


class Clock:
    """A settable clock for the viewer (frame times, held keys, notes)."""

    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


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
    from scene.test_gltf import write_test_glb  # tests/scene (a namespace package on the tests path)

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

    W, H = HUD_W, HUD_H
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
        assert "OVERFLOW" in viewer.status_lines()[2]
        viewer.key("O")
        viewer.key("1")
        viewer.frame(window.fbo)
        assert viewer.last_stats["fragments"]["overflow"] == 0
        # the status line covers the top rows; the rest is guaca's frame, unchanged
        viewer.key("H")
        viewer.frame(window.fbo)
        no_hud = _read(window.fbo)
        assert np.abs(no_hud[:10].astype(int) - shaded[:10]).max() > 30
        below = LINE_HEIGHT * len(viewer.hud_lines(W)) + 4
        assert below < H  # the status line leaves part of the frame uncovered
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


# ----------------------------------------------------------------------------- camera control
def _project(cam: Camera, point, w: int, h: int) -> np.ndarray:
    """Window pixel (x right, y down) of a world point."""
    clip = cam.projection_matrix(w / h) @ cam.view_matrix() @ np.array([*point, 1.0])
    ndc = clip[:3] / clip[3]
    return np.array([(ndc[0] + 1) / 2 * w, (1 - ndc[1]) / 2 * h])


def test_pan_keeps_the_target_under_the_cursor():
    from guaca_py.viewer import CameraController

    cam = Camera(position=(1.0, 2.0, 5.0), target=(0.2, 0.3, 0.0), fov_y=45)
    c = CameraController(cam)
    w, h = 400, 300
    before = _project(c.camera(), cam.target, w, h)
    np.testing.assert_allclose(before, (w / 2, h / 2), atol=1e-9)
    c.pan(40, -25, h)  # drag 40 px right, 25 px up
    np.testing.assert_allclose(_project(c.camera(), cam.target, w, h), (w / 2 + 40, h / 2 - 25), atol=1e-6)
    assert c.distance == pytest.approx(np.linalg.norm(np.subtract(cam.position, cam.target)))  # a slide, no zoom
    np.testing.assert_allclose(c.eye - c.target, np.subtract(cam.position, cam.target), atol=1e-9)


def test_pointer_drag_orbits_with_left_and_pans_with_shift_middle_right():
    from guaca_py.viewer import CameraController
    from guaca_py.viewer.camera import LEFT, MIDDLE, RIGHT

    cam = Camera(position=(0.0, 1.0, 5.0), target=(0.0, 0.0, 0.0))
    for button, mods, pans in [(LEFT, (), False), (LEFT, ("Shift",), True), (MIDDLE, (), True), (RIGHT, (), True)]:
        c = CameraController(cam)
        yaw = c.yaw
        c.pointer_drag(30, 10, button, mods, 300)
        assert (c.yaw == yaw) == pans, (button, mods)
        assert (np.linalg.norm(c.target) > 1e-6) == pans, (button, mods)


def test_fit_frames_the_bounds_and_reset_gives_the_scene_camera_back():
    from guaca_py.viewer import CameraController

    cam = Camera(position=(400.0, 463.0, -431.0), target=(0.0, 0.0, 0.0), fov_y=40, near=0.1, far=100)  # too far
    lo, hi = np.array([-1.0, 0.0, -2.0]), np.array([3.0, 1.5, 0.5])
    c = CameraController(cam, (lo, hi))
    assert c.key("C")
    fitted = c.camera()
    np.testing.assert_allclose(fitted.target, (lo + hi) / 2)
    corners = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    px = np.array([_project(fitted, p, 200, 200) for p in corners])
    assert (px > 0).all() and (px < 200).all()  # every corner inside the frame
    assert np.ptp(px, axis=0).max() > 200 * 0.4  # and the scene fills a good part of it
    dist = np.linalg.norm(np.subtract(fitted.position, fitted.target))
    assert fitted.far > dist + np.linalg.norm(hi - lo) / 2  # the far side is not clipped
    assert fitted.position[0] > 0 and fitted.position[2] < 0  # seen from the same direction as before
    assert c.key("R") and c.camera() is cam
    assert not CameraController(cam).fit()  # no bounds, nothing to fit
    empty = CameraController(cam, (np.zeros(3), np.zeros(3)))  # scene_bounds of a scene without meshes
    assert not empty.fit()
    assert empty.camera() is cam  # the view stays as it was


def test_held_keys_move_by_frame_time():
    from guaca_py.viewer import CameraController

    cam = Camera(position=(0.0, 0.0, 4.0), target=(0.0, 0.0, 0.0))
    a, b = CameraController(cam), CameraController(cam)
    assert a.speed == pytest.approx(4.0 * CameraController.MOVE_SPEED)
    assert a.advance({"W"}, 0.2)
    for _ in range(4):
        b.advance({"W"}, 0.05)
    np.testing.assert_allclose(a.target, b.target, atol=1e-12)  # the same distance, however the frames fall
    np.testing.assert_allclose(a.target, (0.0, 0.0, -a.speed * 0.2), atol=1e-12)  # forward is -z here
    c = CameraController(cam)
    c.advance({"D", "E"}, 0.1)
    np.testing.assert_allclose(c.target, (c.speed * 0.1, c.speed * 0.1, 0.0), atol=1e-12)
    assert not c.advance({"W", "S"}, 0.1)  # opposite keys cancel
    assert not c.advance({"M"}, 0.1)  # not a movement key
    d = CameraController(cam)
    d.advance({"W"}, 10.0)  # a stalled frame moves one capped step, not ten seconds' worth
    assert np.linalg.norm(d.target) == pytest.approx(d.speed * CameraController.MAX_STEP_S)


# ----------------------------------------------------------------------------- the viewer's frame loop
def test_held_key_fps_and_screenshot_note(window, scene_file, tmp_path, monkeypatch):
    from guaca_py.scene.loader import load_scene
    from guaca_py.viewer import Viewer
    from guaca_py.viewer.app import NOTE_SECONDS
    from guaca_py.viewer.window import connect

    monkeypatch.chdir(tmp_path)  # P saves into the working directory
    clock = Clock()
    viewer = Viewer(window.ctx, load_scene(scene_file), clock=clock)
    try:
        window.use()
        monkeypatch.setattr(window, "keys", Keys)
        connect(window, viewer)
        viewer.frame(window.fbo)
        assert viewer.status_lines()[0].startswith("fps -")  # one frame: no rate yet
        window.key_event_func(window.keys.W, window.keys.ACTION_PRESS, None)  # through the window's key map
        assert viewer.held == {"W"}
        target = viewer.controller.target.copy()
        for _ in range(3):
            clock.t += 0.125
            viewer.frame(window.fbo)
        moved = np.linalg.norm(viewer.controller.target - target)
        assert moved == pytest.approx(viewer.controller.speed * 0.375)
        window.key_event_func(window.keys.W, window.keys.ACTION_RELEASE, None)
        clock.t += 0.125
        viewer.frame(window.fbo)
        assert np.linalg.norm(viewer.controller.target - target) == pytest.approx(moved)  # stopped with the key
        assert viewer.status_lines()[0].startswith("8.0 fps 125 ms/frame | ")
        assert viewer.fps() == pytest.approx((8.0, 125.0))

        window.key_event_func(window.keys.P, window.keys.ACTION_PRESS, None)
        viewer.frame(window.fbo)
        assert (tmp_path / "guaca_screenshot_000.png").is_file()
        notes = [text for text, kind in viewer.hud_lines(HUD_W) if kind == "note"]
        assert notes == ["screenshot saved: guaca_screenshot_000.png"]
        top = _read(window.fbo)[: LINE_HEIGHT * len(viewer.hud_lines(HUD_W)) + 4].astype(int)
        yellow = (top[..., 0] > 200) & (top[..., 1] > 170) & (top[..., 2] < 100)
        assert yellow.sum() > 50  # the note is drawn, in its own colour
        clock.t += NOTE_SECONDS + 0.01
        viewer.frame(window.fbo)
        assert not [kind for _, kind in viewer.hud_lines(HUD_W) if kind == "note"]
        top = _read(window.fbo)[: LINE_HEIGHT * len(viewer.hud_lines(HUD_W)) + 4].astype(int)
        assert not ((top[..., 0] > 200) & (top[..., 1] > 170) & (top[..., 2] < 100)).sum()  # and gone after 2 s
    finally:
        viewer.release()


def test_status_line_contents(window, scene_file):
    from guaca_py.scene.loader import load_scene
    from guaca_py.viewer import Viewer
    from guaca_py.viewer.app import KEYS

    clock = Clock()
    viewer = Viewer(window.ctx, load_scene(scene_file), clock=clock)
    try:
        window.use()
        for _ in range(2):
            viewer.frame(window.fbo)
            clock.t += 0.5
        lines = viewer.status_lines()
        assert (
            lines[0] == f"{viewer.fps()[0]:.1f} fps {viewer.fps()[1]:.0f} ms/frame | {viewer.method} | shaded | orbit"
        )
        assert lines[0].startswith("2.0 fps 500 ms/frame")
        assert lines[1].startswith("pass ms (") and "geometry" in lines[1] and "composite" in lines[1]
        assert lines[2].startswith(f"fragments stored {viewer.last_stats['fragments']['stored']}")
        help_text = " ".join(lines[3:])
        for key, action in KEYS.items():
            assert f"{key} {action}" in help_text
        assert "pan" in help_text and "zoom" in help_text and "W/A/S/D/Q/E" in help_text
        assert lines[3].startswith("keys: M next method  N") and lines[4].startswith("mouse: drag orbit")
        wrapped = viewer.hud_lines(HUD_W)
        from guaca_py.viewer.hud import hud_font

        assert max(hud_font().getlength(text) for text, _ in wrapped) <= HUD_W - 6  # wrapped to the frame
        viewer.key("F")
        assert viewer.status_lines()[0].endswith("| fly")
    finally:
        viewer.release()


@pytest.mark.parametrize(
    "view,stat", [("depth_complexity", "pixel_max"), ("light_count", "tile_max")], ids=["depth", "lights"]
)
def test_heat_views_scale_to_the_frame(window, scene_file, view, stat):
    from guaca_py.scene.loader import load_scene
    from guaca_py.viewer import Viewer
    from guaca_py.viewer.app import HEAT_VIEWS, VIEWS

    pass_name = VIEWS[view]
    viewer = Viewer(window.ctx, load_scene(scene_file), view=view)
    try:
        window.use()
        viewer.show_hud = False
        viewer.frame(window.fbo)
        info = viewer.last_stats["debug_views"][pass_name]
        top = info[stat]
        assert (
            1 <= top < viewer.renderer().pass_named(pass_name).SETTINGS["max"].default
        )  # the fixed scale was too wide
        assert viewer.heat_max[view] == top == info["max_shown"]  # the first frame was drawn again on its own scale
        assert viewer.renderer().pass_named(pass_name).settings["max"] == top
        img = _read(window.fbo)[: HUD_H - legend_rows(HUD_H)].astype(float) / 255
        hottest = np.abs(img - heat_color(top, top)).max(axis=-1) <= 1.5 / 255
        assert hottest.sum() > 0  # the frame's largest value reaches the top of the scale (red)
        assert f"heat scale 0-{top} {HEAT_VIEWS[view][1]} (frame max {top})" in viewer.status_lines()[2]
    finally:
        viewer.release()


# ----------------------------------------------------------------------------- the font
def test_status_text_keeps_its_spaces():
    from PIL import Image, ImageDraw, ImageFont

    from guaca_py.viewer.hud import draw_line, hud_font, text_image

    def gaps(px: np.ndarray) -> list[int]:
        """Widths of the blank column runs between inked columns."""
        ink = (px[..., :3].max(axis=-1) > 128).any(axis=0)
        cols = np.flatnonzero(ink)
        return [int(b - a - 1) for a, b in zip(cols[:-1], cols[1:]) if b - a > 1]

    digit = hud_font().getlength("0")
    assert max(gaps(text_image(["1 1"], 80))) >= digit  # a space is at least a digit wide
    assert max(gaps(text_image(["11"], 80))) < digit
    thin = ImageFont.load_default(size=13)  # proportional, with thin spaces
    assert thin.getlength(" ") < thin.getlength("0")
    img = Image.new("RGB", (80, 20))
    draw_line(ImageDraw.Draw(img), (2, 2), "1 1", thin, (255, 255, 255))
    assert max(gaps(np.asarray(img))) >= thin.getlength("0")


def test_wrap_parts_breaks_between_parts():
    from guaca_py.viewer.app import wrap_parts

    parts = ["keys:", "M next method", "N previous method", "1 shaded", "2 depth complexity", "R reset view"]
    lines = wrap_parts(parts, "  ", 40)
    assert lines == ["keys:  M next method  N previous method", "  1 shaded  2 depth complexity", "  R reset view"]
    assert wrap_parts(parts, "  ", 0) == ["  ".join(parts)]
    long = wrap_parts(["status", "a part much longer than one line of the status"], " | ", 20)
    assert all(len(line) <= 20 for line in long) and long[0] == "status"
    assert (
        " ".join(line.strip(" |") for line in long).split()
        == "status a part much longer than one line of the status".split()
    )


def test_overflow_key_with_method_auto(window, scene_file):
    # `auto` names no method of its own: the overflow mode asks the method auto picked
    from guaca_py.scene.loader import load_scene
    from guaca_py.viewer import Viewer

    viewer = Viewer(window.ctx, load_scene(scene_file), method="auto")
    try:
        window.use()
        viewer.key("O")
        viewer.frame(window.fbo)
        assert viewer.last_stats["method"] != "auto"
        assert viewer.last_stats["fragments"].get("overflow", 0) > 0
    finally:
        viewer.release()
