"""`guaca view`: drive the Viewer from a moderngl-window window (or a headless one)."""

from __future__ import annotations

from pathlib import Path

from ..errors import DeviceError
from ..scene.graph import Scene
from .app import KEYS, Viewer

FLY_KEYS = {"W": (1, 0, 0), "S": (-1, 0, 0), "A": (0, -1, 0), "D": (0, 1, 0), "E": (0, 0, 1), "Q": (0, 0, -1)}


def _window_class(headless: bool):
    try:
        import moderngl_window as mglw
    except ImportError as exc:
        raise DeviceError(
            f'the viewer needs moderngl-window ({exc}); install it with `pip install "guaca_py[viewer]"`'
        ) from exc
    name = "headless" if headless else None
    return mglw, mglw.get_local_window_cls(name)


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
    keys = window.keys
    codes = {getattr(keys, k if not k.isdigit() else f"NUMBER_{k}", None): k for k in list(KEYS) + list(FLY_KEYS)}
    step = max(viewer.controller.distance * 0.05, 1e-3)

    def on_key(key, action, modifiers):
        name = codes.get(key)
        if name is None or action != keys.ACTION_PRESS:
            return
        if name in FLY_KEYS and viewer.controller.mode == "fly":
            f, r, u = FLY_KEYS[name]
            viewer.controller.move(f * step, r * step, u * step)
        elif name in KEYS:
            viewer.key(name)

    window.key_event_func = on_key
    window.mouse_drag_event_func = lambda x, y, dx, dy: viewer.controller.drag(dx, dy)
    window.mouse_scroll_event_func = lambda dx, dy: viewer.controller.zoom(dy)
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
