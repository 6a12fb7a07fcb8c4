"""Notebooks: an interactive view of a Scene through jupyter_rfb (`pip install "guaca_py[notebook]"`).

A finished frame already shows itself as a cell's value (`FrameResult._repr_png_`). `widget(scene)`
adds interaction: drag to orbit, shift-, middle- or right-drag to pan, wheel to zoom, and the
viewer's keys (M / N switch the transparency method, R resets the view, C fits the scene, F toggles
fly, W/A/S/D/Q/E step). The widget renders through a Renderer with its own headless context and
sends the frame's pixels to the browser.

`InteractiveView` is the widget without Jupyter: it takes jupyter_rfb's event dicts and renders
frames, so the same logic runs (and is tested) where jupyter_rfb is not installed.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .methods import method_class, method_ids
from .renderer import Renderer
from .scene.gltf import scene_bounds
from .scene.graph import Scene
from .viewer.app import cycle
from .viewer.camera import MOVE_KEYS, CameraController

try:
    from jupyter_rfb import RemoteFrameBuffer
except ImportError:  # the optional extra: InteractiveView works without it, the widget does not
    RemoteFrameBuffer = None

INSTALL_HINT = 'the notebook widget needs jupyter_rfb: pip install "guaca_py[notebook]"'
WHEEL_STEP = 100.0  # wheel delta (browser pixels) of one zoom step
KEY_STEP_S = 0.1  # a movement key press moves as far as a held key does in this many seconds


class InteractiveView:
    """Camera and method state of an interactive view, driven by jupyter_rfb events; `draw()` renders a frame.

    `size` is the frame in physical pixels until the first resize event says otherwise.
    """

    def __init__(
        self,
        scene: Scene,
        *,
        pipeline="default",
        method: str | None = None,
        size: tuple[int, int] = (640, 400),
        renderer: Renderer | None = None,
    ):
        self.scene = scene
        self.owns_renderer = renderer is None
        self.renderer = renderer or Renderer(pipeline)  # its own headless context
        if method is not None:
            self.renderer.set_method(method)
        self.controller = CameraController(scene.camera, scene_bounds(scene.nodes))
        self.size = (int(size[0]), int(size[1]))
        self.logical_height = self.size[1]  # pointer coordinates are logical (CSS) pixels
        self.last_stats: dict = {}
        self._drag: tuple[int, float, float] | None = None  # (button, x, y) of the drag under way

    @property
    def method(self) -> str:
        """The transparency method frames are rendered with."""
        return self.renderer.method.id

    def methods(self) -> list[str]:
        """Transparency methods this device runs."""
        return [m for m in method_ids() if method_class(m).unsupported_reason(self.renderer.caps) is None]

    def set_method(self, mid: str) -> None:
        """Switch the transparency method."""
        if mid != self.method:
            self.renderer.set_method(mid)

    def handle_event(self, event: dict) -> bool:
        """Apply one jupyter_rfb event (old- or new-style keys); returns whether the frame must be drawn again."""
        kind = event.get("type") or event.get("event_type")
        if kind == "resize":
            ratio = event.get("ratio") or event.get("pixel_ratio") or 1.0
            w = event.get("pwidth") or event["width"] * ratio
            h = event.get("pheight") or event["height"] * ratio
            self.size = (max(int(w), 1), max(int(h), 1))
            self.logical_height = max(int(event["height"]), 1)
            return True
        if kind == "pointer_down":
            self._drag = (int(event.get("button", 0)), float(event["x"]), float(event["y"]))
            return False
        if kind == "pointer_move" and self._drag is not None:
            button, x0, y0 = self._drag
            x, y = float(event["x"]), float(event["y"])
            self._drag = (button, x, y)
            self.controller.pointer_drag(x - x0, y - y0, button, event.get("modifiers", ()), self.logical_height)
            return True
        if kind == "pointer_up":
            self._drag = None
            return False
        if kind == "wheel":
            self.controller.zoom(-float(event.get("dy", 0.0)) / WHEEL_STEP)  # wheel down (positive dy) backs away
            return True
        if kind == "key_down":
            return self.key(str(event.get("key", "")))
        return False

    def key(self, key: str) -> bool:
        """A key press by name (case does not matter); returns whether it changed the frame."""
        name = key.upper() if len(key) == 1 else key
        if name in ("M", "N"):
            self.set_method(cycle(self.methods(), self.method, 1 if name == "M" else -1))
            return True
        if name in MOVE_KEYS:
            return self.controller.advance({name}, KEY_STEP_S)
        return self.controller.key(name)

    def draw(self) -> np.ndarray:
        """Render the current view: (H, W, 3) uint8, row 0 at the top."""
        w, h = self.size
        frame = self.renderer.render(replace(self.scene, camera=self.controller.camera()), w, h)
        self.last_stats = frame.stats
        return frame.image

    def release(self) -> None:
        """Free the renderer (when this view made it)."""
        if self.owns_renderer:
            self.renderer.release()


def widget(scene: Scene, **kwargs) -> GuacaWidget:
    """An interactive widget on `scene` (a cell's value shows it); keyword arguments go to GuacaWidget."""
    if RemoteFrameBuffer is None:
        raise ImportError(INSTALL_HINT)
    return GuacaWidget(scene, **kwargs)


if RemoteFrameBuffer is not None:

    class GuacaWidget(RemoteFrameBuffer):
        """jupyter_rfb widget: browser events go to an InteractiveView, its frames come back as images."""

        def __init__(
            self,
            scene: Scene,
            *,
            pipeline="default",
            method: str | None = None,
            width: int = 640,
            height: int = 400,
            **kwargs,
        ):
            super().__init__(css_width=f"{width}px", css_height=f"{height}px", **kwargs)
            self.interaction = InteractiveView(scene, pipeline=pipeline, method=method, size=(width, height))
            self.title = self.interaction.method
            self._pickers: list = []  # method dropdowns to keep in step with the M / N keys

        def handle_event(self, event: dict) -> None:
            """jupyter_rfb's event callback: apply the event, draw again when it changed the view."""
            if self.interaction.handle_event(event):
                self.request_draw()
            for picker in self._pickers:
                picker.value = self.interaction.method
            if event.get("type", event.get("event_type")) == "close":
                self.interaction.release()

        def get_frame(self) -> np.ndarray:
            """jupyter_rfb's draw callback: the frame's pixels."""
            image = self.interaction.draw()
            self.title = self.interaction.method
            return image

        def method_picker(self):
            """A dropdown of the methods this device runs, bound to the widget (display it beside the widget)."""
            import ipywidgets

            picker = ipywidgets.Dropdown(
                options=self.interaction.methods(), value=self.interaction.method, description="method"
            )

            def changed(change) -> None:
                self.interaction.set_method(change["new"])
                self.request_draw()

            picker.observe(changed, names="value")
            self._pickers.append(picker)
            return picker
