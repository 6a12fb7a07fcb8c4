"""`guaca view`: drive the Viewer from a moderngl-window window (or a headless one)."""

from __future__ import annotations

from pathlib import Path

from ..errors import DeviceError
from ..scene.graph import Scene
from .app import KEYS, Viewer
from .camera import LEFT, MIDDLE, MOVE_KEYS, RIGHT


def _window_class(headless: bool):
    try:
        import moderngl_window as mglw
    except ImportError as exc:
        raise DeviceError(
            f'the viewer needs moderngl-window ({exc}); install it with `pip install "guaca_py[viewer]"`'
        ) from exc
    name = "headless" if headless else None
    return mglw, mglw.get_local_window_cls(name)


def connect(window, viewer: Viewer) -> None:
    """Route a moderngl-window window's key, drag and scroll events to `viewer`."""
    keys = window.keys
    codes = {getattr(keys, k if not k.isdigit() else f"NUMBER_{k}", None): k for k in list(KEYS) + list(MOVE_KEYS)}
    codes.pop("undefined", None)  # a toolkit without keys (headless) names every key so
    codes.pop(None, None)

    def on_key(key, action, modifiers):
        name = codes.get(key)
        if name in MOVE_KEYS:  # held: the camera moves every frame until the key comes up
            viewer.hold(name, action == keys.ACTION_PRESS)
        elif name in KEYS and action == keys.ACTION_PRESS:
            viewer.key(name)

    def on_drag(x, y, dx, dy):
        buttons = window.mouse_states
        button = LEFT if buttons.left else MIDDLE if buttons.middle else RIGHT if buttons.right else 0
        modifiers = ("Shift",) if window.modifiers.shift else ()
        viewer.controller.pointer_drag(dx, dy, button, modifiers, window.size[1])

    window.key_event_func = on_key
    window.mouse_drag_event_func = on_drag
    window.mouse_scroll_event_func = lambda dx, dy: viewer.controller.zoom(dy)


def run_viewer(
    scene: Scene,
    *,
    width: int = 1024,
    height: int = 768,
    pipeline="default",
    method: str | None = None,
    view: str = "shaded",
    headless: bool = False,
    frames: int = 0,
    screenshot: str | Path | None = None,
) -> Viewer:
    """Open a window on `scene` and run until it closes (or for `frames` frames); returns the Viewer."""
    if headless and not frames:
        frames = 1  # nothing could ever close a headless window
    try:
        mglw, window_cls = _window_class(headless)
        window = window_cls(
            title="guaca view",
            size=(width, height),
            gl_version=(4, 5),
            resizable=not headless,
            vsync=True,
            backend="egl" if headless else None,  # headless windows on machines without a display
        )
    except DeviceError:
        raise
    except Exception as exc:  # no display, no GL 4.5 window: the toolkit's own exception types vary
        raise DeviceError(
            f"cannot open a window: {exc}; without a display use `guaca view --headless --frames N --screenshot out.png`"
        ) from exc
    mglw.activate_context(window=window)
    viewer = Viewer(window.ctx, scene, pipeline=pipeline, method=method, view=view)
    connect(window, viewer)
    try:
        while not window.is_closing:
            window.use()
            if screenshot is not None and viewer.frames == (frames - 1 if frames else 0):
                viewer.screenshot_requests.append(Path(screenshot))  # of the last frame (or the first)
            viewer.frame(window.fbo, window.buffer_size)
            window.swap_buffers()
            if frames and viewer.frames >= frames:
                window.close()
    finally:
        viewer.release()
        window.destroy()
    return viewer
