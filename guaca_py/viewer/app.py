"""The viewer's frame loop, independent of the window toolkit: this is what an embedding copies.

Per frame: apply the camera, let guaca_py render straight into the window's framebuffer
(`target=`, no read-back), draw the application's own overlay on top. guaca_py makes its
context current and restores the GL state it changed, so the overlay code needs no care.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import GuacaError
from ..methods import method_class, method_ids
from ..pipeline.config import PassConfig, load_pipeline
from ..pipeline.settings import resolve_settings
from ..registry import PASSES
from ..renderer import Renderer
from ..scene.graph import Scene
from .camera import CameraController
from .hud import Hud

#: view name -> debug pass appended to the pipeline (None: the pipeline as configured)
VIEWS = {"shaded": None, "depth_complexity": "debug_depth_complexity", "light_count": "debug_light_count"}
#: key -> action, shown in the help line (window.py maps toolkit key codes to these names)
KEYS = {
    "M": "next method",
    "N": "previous method",
    "1": "shaded",
    "2": "depth complexity",
    "3": "light count",
    "O": "overflow",  # a tiny A-buffer budget, to see overflow handled (and counted) on screen
    "F": "orbit/fly",
    "P": "screenshot",
    "H": "status line",
}
STATS_EVERY = 10  # frames between timed frames (timing syncs the GPU once per pass)
OVERFLOW_BYTES_PER_PIXEL = 4  # the "overflow" key's A-buffer budget: about one node per 9 pixels


def view_pipeline(base, view: str):
    """`base` PipelineConfig with the debug pass of `view` appended."""
    config = load_pipeline(base)
    extra = VIEWS[view]
    if extra is None:
        return config
    settings = resolve_settings(PASSES.get(extra).SETTINGS, {}, lambda k, r, h: GuacaError(r))
    return replace(config, passes=[*config.passes, PassConfig(extra, settings)])


class Viewer:
    """Renders a Scene into a host framebuffer each frame and reacts to named keys and mouse input."""

    def __init__(self, ctx, scene: Scene, pipeline="default", method: str | None = None, view: str = "shaded"):
        self.ctx = ctx
        self.scene = scene
        self.pipeline = pipeline
        self.controller = CameraController(scene.camera)
        self.renderers: dict[str, Renderer] = {}
        self._applied: dict[str, tuple] = {}  # view -> (method, overflow mode) its renderer runs
        self.view = view
        self.method = method or load_pipeline(pipeline).transparency["method"]
        self.overflow_mode = False
        self.show_hud = True
        self.hud = Hud(ctx)
        self.frames = 0
        self.last_stats: dict = {}
        self.message = ""
        self._changed = False  # a key changed what is rendered: time the next frame
        self.screenshot_requests: list[Path] = []
        self.screenshots_taken: list[Path] = []
        self.renderer()  # build the first one now: configuration errors surface before the loop

    # ------------------------------------------------------------------ guaca side
    def renderer(self, size: tuple[int, int] | None = None) -> Renderer:
        """The Renderer of the current view (one per view, made on first use, on the host context)."""
        r = self.renderers.get(self.view)
        if r is None:
            r = self.renderers[self.view] = Renderer(view_pipeline(self.pipeline, self.view), ctx=self.ctx)
        budget = None
        if self.overflow_mode and size and "budget_mb" in method_class(self.method).settings_schema():
            budget = size[0] * size[1] * OVERFLOW_BYTES_PER_PIXEL / 2**20
        if self._applied.get(self.view) != (self.method, budget):
            r.set_method(self.method, {"budget_mb": budget} if budget else None)
            self._applied[self.view] = (self.method, budget)
        return r

    def runnable_methods(self) -> list[str]:
        """Transparency methods this device runs."""
        caps = self.renderer().caps
        return [m for m in method_ids() if method_class(m).unsupported_reason(caps) is None]

    def frame(self, fbo, size: tuple[int, int] | None = None) -> None:
        """Render one frame into `fbo` (the window's framebuffer), then the status line."""
        w, h = size or fbo.size
        self.scene.camera = self.controller.camera()
        timed = self.frames % STATS_EVERY == 0 or self._changed
        self._changed = False
        note = ""
        try:
            result = self.renderer((w, h)).render(self.scene, w, h, target=fbo, read_back=False, stats=timed)
        except GuacaError as exc:  # e.g. a method this view cannot run with: say so, fall back
            note = str(exc).splitlines()[0]
            self.view = "shaded"
            result = self.renderer((w, h)).render(self.scene, w, h, target=fbo, read_back=False, stats=timed)
        self.message = note or next(iter(result.stats.get("warnings", [])), "")
        if timed or not self.last_stats:
            self.last_stats = result.stats
        else:
            self.last_stats["fragments"] = result.stats.get("fragments", {})
        self.frames += 1
        while self.screenshot_requests:
            self.screenshots_taken.append(self._save_screenshot(fbo, (w, h), self.screenshot_requests.pop(0)))
        if self.show_hud:
            self.hud.draw(fbo, self.status_lines())

    def _save_screenshot(self, fbo, size, path: Path) -> Path:
        """The window's pixels as they are after guaca's frame (before the status line)."""
        from PIL import Image

        w, h = size
        px = np.frombuffer(fbo.read(viewport=(0, 0, w, h), components=3), np.uint8).reshape(h, w, 3)[::-1]
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.ascontiguousarray(px)).save(path)
        return path

    def status_lines(self) -> list[str]:
        """The status line: method, view, per-pass times, fragment counters."""
        s = self.last_stats
        passes = " ".join(f"{k} {v['ms']:.1f}" for k, v in s.get("passes", {}).items())
        fr = s.get("fragments", {})
        frags = f"stored {fr.get('stored', 0)}"
        if fr.get("overflow"):
            frags += f" OVERFLOW {fr['overflow']}"
        budget = " (tiny A-buffer budget)" if self.overflow_mode else ""
        line = f"{self.method}{budget} | {self.view} | {self.controller.mode} | ms ({s.get('timer', '?')}): {passes}"
        lines = [line, f"fragments {frags}", "keys: " + " ".join(f"{k} {v}" for k, v in KEYS.items())]
        if self.message:
            lines.append(self.message)
        return lines

    # ------------------------------------------------------------------ input
    def key(self, name: str) -> None:
        """React to a key by name (see KEYS)."""
        self._changed = True
        if name in ("M", "N"):
            methods = self.runnable_methods()
            i = methods.index(self.method) if self.method in methods else 0
            self.method = methods[(i + (1 if name == "M" else -1)) % len(methods)]
        elif name in ("1", "2", "3"):
            self.view = list(VIEWS)[int(name) - 1]
        elif name == "O":
            self.overflow_mode = not self.overflow_mode
        elif name == "F":
            self.controller.toggle_mode()
        elif name == "P":
            self.screenshot_requests.append(Path(f"guaca_screenshot_{len(self.screenshots_taken):03d}.png"))
        elif name == "H":
            self.show_hud = not self.show_hud

    def release(self) -> None:
        """Free every renderer and the overlay."""
        for r in self.renderers.values():
            r.release()
        self.renderers.clear()
        self.hud.release()
