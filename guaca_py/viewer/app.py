"""The viewer's frame loop, independent of the window toolkit: this is what an embedding copies.

Per frame: apply the camera, let guaca_py render straight into the window's framebuffer
(`target=`, no read-back), draw the application's own overlay on top. guaca_py makes its
context current and restores the GL state it changed, so the overlay code needs no care.
"""

from __future__ import annotations

import textwrap
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import GuacaError
from ..methods import method_class, method_ids
from ..pipeline.config import PassConfig, load_pipeline
from ..pipeline.settings import resolve_settings
from ..registry import PASSES
from ..renderer import Renderer
from ..scene.gltf import scene_bounds
from ..scene.graph import Scene
from .camera import CAMERA_KEYS, MOVE_KEYS, CameraController
from .hud import Hud, hud_font

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
    **CAMERA_KEYS,
    "P": "screenshot",
    "H": "status line",
}
#: the help lines' mouse and held-key part
MOUSE_HELP = ("drag orbit (fly: look)", "shift/middle/right drag pan", "wheel zoom", "hold W/A/S/D/Q/E move")
#: heat view -> (the entry of its debug pass's stats that holds the frame's largest value, its unit)
HEAT_VIEWS = {"depth_complexity": ("pixel_max", "fragments/pixel"), "light_count": ("tile_max", "lights/tile")}
STATS_EVERY = 10  # frames between timed frames (timing syncs the GPU once per pass)
OVERFLOW_BYTES_PER_PIXEL = 4  # the "overflow" key's A-buffer budget: about one node per 9 pixels
NOTE_SECONDS = 2.0  # how long a note (a screenshot was saved) stays on screen
FPS_FRAMES = 10  # frames the fps figure averages over


def view_pipeline(base, view: str):
    """`base` PipelineConfig with the debug pass of `view` appended."""
    config = load_pipeline(base)
    extra = VIEWS[view]
    if extra is None:
        return config
    settings = resolve_settings(PASSES.get(extra).SETTINGS, {}, lambda k, r, h: GuacaError(r))
    return replace(config, passes=[*config.passes, PassConfig(extra, settings)])


class Viewer:
    """Renders a Scene into a host framebuffer each frame and reacts to named keys and mouse input.

    `clock` (seconds, monotonic) times frames, held-key movement and notes; tests pass their own.
    """

    def __init__(
        self,
        ctx,
        scene: Scene,
        pipeline="default",
        method: str | None = None,
        view: str = "shaded",
        clock: Callable[[], float] = time.perf_counter,
    ):
        self.ctx = ctx
        self.scene = scene
        self.pipeline = pipeline
        self.clock = clock
        self.controller = CameraController(scene.camera, scene_bounds(scene.nodes))
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
        self.held: set[str] = set()  # MOVE_KEYS held down: the camera moves each frame by the frame's time
        self.heat_max: dict[str, int] = {}  # heat view -> top of its scale (the last frame's largest value)
        self.notes: list[tuple[str, float]] = []  # (text, clock time it goes away)
        self._intervals: deque[float] = deque(maxlen=FPS_FRAMES)  # seconds between frame starts
        self._last_frame_at: float | None = None
        self._changed = False  # a key changed what is rendered: time the next frame
        self.screenshot_requests: list[Path] = []
        self.screenshots_taken: list[Path] = []
        self._key_shots: set[Path] = set()  # requested by the P key: a failure is a note, not an error
        self.renderer()  # build the first one now: configuration errors surface before the loop

    # ------------------------------------------------------------------ guaca side
    def renderer(self, size: tuple[int, int] | None = None) -> Renderer:
        """The Renderer of the current view (one per view, made on first use, on the host context)."""
        r = self.renderers.get(self.view)
        if r is None:
            r = self.renderers[self.view] = Renderer(view_pipeline(self.pipeline, self.view), ctx=self.ctx)
        budget = None
        # `auto` names no method: the one it picked for this renderer decides
        mid = r.method.id if self.method == "auto" else self.method
        if self.overflow_mode and size and "budget_mb" in method_class(mid).settings_schema():
            budget = size[0] * size[1] * OVERFLOW_BYTES_PER_PIXEL / 2**20
        if self._applied.get(self.view) != (self.method, budget):
            r.set_method(self.method, {"budget_mb": budget} if budget else None)
            self._applied[self.view] = (self.method, budget)
        return r

    def runnable_methods(self) -> list[str]:
        """Transparency methods this device runs."""
        caps = self.renderer().caps
        return [m for m in method_ids() if method_class(m).unsupported_reason(caps) is None]

    def _render(self, fbo, w: int, h: int, timed: bool):
        """One guaca frame of the current view into `fbo`, its heat scale (if any) set from the last frame."""
        r = self.renderer((w, h))
        if self.view in self.heat_max:
            p = r.pass_named(VIEWS[self.view])
            p.settings = {**p.settings, "max": self.heat_max[self.view]}
        return r.render(self.scene, w, h, target=fbo, read_back=False, stats=timed)

    def _measure_heat(self, stats: dict) -> bool:
        """Keep the frame's largest heat value as the next scale; returns whether the scale changed."""
        heat = HEAT_VIEWS.get(self.view)
        value = stats.get("debug_views", {}).get(VIEWS[self.view], {}).get(heat[0]) if heat else None
        if value is None:
            return False
        top = max(int(value), 1)  # an empty frame keeps a scale of one
        changed = self.heat_max.get(self.view) != top
        self.heat_max[self.view] = top
        return changed

    def frame(self, fbo, size: tuple[int, int] | None = None) -> None:
        """Render one frame into `fbo` (the window's framebuffer), then the status line."""
        w, h = size or fbo.size
        now = self.clock()
        dt = 0.0 if self._last_frame_at is None else now - self._last_frame_at
        self._last_frame_at = now
        if dt > 0.0:
            self._intervals.append(dt)
        self.controller.advance(self.held, dt)
        self.scene.camera = self.controller.camera()
        timed = self.frames % STATS_EVERY == 0 or self._changed
        self._changed = False
        note = ""
        first_heat_frame = self.view in HEAT_VIEWS and self.view not in self.heat_max
        try:
            result = self._render(fbo, w, h, timed)
        except GuacaError as exc:  # e.g. a method this view cannot run with: say so, fall back
            note = str(exc).splitlines()[0]
            self.view = "shaded"
            first_heat_frame = False
            result = self._render(fbo, w, h, timed)
        if self._measure_heat(result.stats) and first_heat_frame:
            result = self._render(fbo, w, h, timed)  # the view's first frame: again, on its own scale
        self.message = note or next(iter(result.stats.get("warnings", [])), "")
        if timed or not self.last_stats:
            self.last_stats = result.stats
        else:
            for key in ("fragments", "debug_views"):  # counters of every frame; times of timed ones
                self.last_stats[key] = result.stats.get(key, {})
        self.frames += 1
        while self.screenshot_requests:
            path = self.screenshot_requests.pop(0)
            try:
                self.screenshots_taken.append(self._save_screenshot(fbo, (w, h), path))
            except GuacaError as exc:
                if path not in self._key_shots:  # a screenshot the caller asked for: its failure is the caller's
                    raise
                self.note(f"screenshot not saved: {exc}")
                continue
            self.note(f"screenshot saved: {path}")
        if self.show_hud:
            self.hud.draw(fbo, self.hud_lines(w))

    def _save_screenshot(self, fbo, size, path: Path) -> Path:
        """The window's pixels as they are after guaca's frame (before the status line)."""
        from PIL import Image

        from ..output import IMAGE_SUFFIXES, check_writable, write_atomic

        w, h = size
        px = np.frombuffer(fbo.read(viewport=(0, 0, w, h), components=3), np.uint8).reshape(h, w, 3)[::-1]
        # the checks and the atomic write of every output: never over an input, a device or a FIFO
        path = check_writable(path, "screenshot", IMAGE_SUFFIXES)
        fmt = Image.registered_extensions().get(path.suffix.lower())
        image = Image.fromarray(np.ascontiguousarray(px))
        return write_atomic(path, lambda tmp: image.save(tmp, format=fmt), "screenshot")

    def _free_screenshot_name(self) -> Path:
        """The next `guaca_screenshot_NNN.png` that neither exists nor is requested: P never replaces a file."""
        n = len(self.screenshots_taken)
        while (p := Path(f"guaca_screenshot_{n:03d}.png")).exists() or p in self.screenshot_requests:
            n += 1
        return p

    # ------------------------------------------------------------------ status line
    def note(self, text: str, seconds: float = NOTE_SECONDS) -> None:
        """Show `text` under the status line for `seconds`."""
        self.notes.append((text, self.clock() + seconds))

    def fps(self) -> tuple[float, float] | None:
        """(frames per second, milliseconds per frame) over the last FPS_FRAMES frames, None before the second frame."""
        if not self._intervals:
            return None
        mean = sum(self._intervals) / len(self._intervals)
        return 1.0 / mean, mean * 1e3

    def heat_scale(self) -> str:
        """The heat view's scale as text ('' in the shaded view)."""
        heat = HEAT_VIEWS.get(self.view)
        if not heat:
            return ""
        info = self.last_stats.get("debug_views", {}).get(VIEWS[self.view], {})
        if info.get("supported") is False:
            return "heat: not available for this method"
        shown = info.get("max_shown", "?")
        return f"heat scale 0-{shown} {heat[1]} (frame max {info.get(heat[0], '?')})"

    def hud_lines(self, width: int = 0) -> list[tuple[str, str]]:
        """The status line as (text, kind) lines: fps, method and view; pass times; counters; keys; notes.

        `width` (pixels) wraps the lines to the frame; 0 leaves each on one line.
        """
        s = self.last_stats
        rate = self.fps()
        fps = f"{rate[0]:.1f} fps {rate[1]:.0f} ms/frame" if rate else "fps -"
        budget = " (tiny A-buffer budget)" if self.overflow_mode else ""
        fr = s.get("fragments", {})
        counters = [f"fragments stored {fr.get('stored', 0)}"]
        if fr.get("overflow"):
            counters[0] += f" OVERFLOW {fr['overflow']}"
        if self.heat_scale():
            counters.append(self.heat_scale())
        now = self.clock()
        self.notes = [(text, until) for text, until in self.notes if until > now]
        notes = [text for text, _ in self.notes] + ([self.message] if self.message else [])
        passes = [f"{k} {v['ms']:.1f}" for k, v in s.get("passes", {}).items()]
        keys = [f"{k} {v}" for k, v in KEYS.items()]
        # each line as its parts and their separator: wrapping breaks between parts, not inside one
        lines = [
            ([fps, f"{self.method}{budget}", self.view, self.controller.mode], " | ", "status"),
            (labelled(f"pass ms ({s.get('timer', '?')}):", passes), " ", "status"),
            (counters, " | ", "status"),
            (labelled("keys:", keys), "  ", "status"),
            (labelled("mouse:", list(MOUSE_HELP)), " | ", "status"),
            *(([text], "", "note") for text in notes),
        ]
        # wrap to the frame: the font is monospaced, so a line's width is its length in characters
        chars = max(int((width - 12) // hud_font().getlength("0")), 40) if width else 0
        return [(text, kind) for parts, sep, kind in lines for text in wrap_parts(parts, sep, chars)]

    def status_lines(self) -> list[str]:
        """The status line's text: fps, method and view; pass times; counters and heat scale; keys; notes."""
        return [text for text, _ in self.hud_lines()]

    # ------------------------------------------------------------------ input
    def key(self, name: str) -> None:
        """React to a key by name (see KEYS)."""
        self._changed = True
        if name in ("M", "N"):
            self.method = cycle(self.runnable_methods(), self.method, 1 if name == "M" else -1)
        elif name in ("1", "2", "3"):
            self.view = list(VIEWS)[int(name) - 1]
        elif name == "O":
            self.overflow_mode = not self.overflow_mode
        elif name == "P":
            path = self._free_screenshot_name()
            self._key_shots.add(path)
            self.screenshot_requests.append(path)
        elif name == "H":
            self.show_hud = not self.show_hud
        else:
            self.controller.key(name)

    def hold(self, name: str, down: bool) -> None:
        """A movement key (MOVE_KEYS) went down or up: held keys move the camera every frame."""
        if name not in MOVE_KEYS:
            return
        if down:
            self.held.add(name)
        else:
            self.held.discard(name)

    def release(self) -> None:
        """Free every renderer and the overlay."""
        for r in self.renderers.values():
            r.release()
        self.renderers.clear()
        self.hud.release()


def labelled(label: str, parts: list[str]) -> list[str]:
    """`parts` with `label` and a space before the first (the label stays with it when a line wraps)."""
    return [f"{label} {parts[0]}", *parts[1:]] if parts else [label]


def wrap_parts(parts: list[str], sep: str, chars: int) -> list[str]:
    """`parts` joined by `sep` into lines of at most `chars` characters (0: one line), breaking only between parts.

    A part longer than a line is broken at its spaces; continued lines are indented by two spaces.
    """
    if not chars:
        return [sep.join(parts)]
    lines: list[str] = []
    for part in parts:
        for piece in textwrap.wrap(part, chars - 2) or [""]:
            if lines and len(lines[-1]) + len(sep) + len(piece) <= chars:
                lines[-1] += sep + piece
            else:
                lines.append(piece if not lines else "  " + piece)
    return lines


def cycle(items: list[str], current: str, step: int) -> str:
    """The item `step` places after `current` in `items`, wrapping around (the first if `current` is not there)."""
    i = items.index(current) if current in items else 0
    return items[(i + step) % len(items)]
