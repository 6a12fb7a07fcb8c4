"""Camera control shared by the viewer window and the notebook widget: orbit, fly, pan, zoom, fit, reset.

Both front ends turn their toolkit's events into the calls below (`pointer_drag`, `zoom`, `key`,
`advance`), so a gesture means the same in a window and in a notebook.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import replace

import numpy as np

from ..scene.graph import Camera

#: held key -> (forward, right, up) direction of movement
MOVE_KEYS = {"W": (1, 0, 0), "S": (-1, 0, 0), "A": (0, -1, 0), "D": (0, 1, 0), "E": (0, 0, 1), "Q": (0, 0, -1)}
#: key -> camera action, shown in the help line
CAMERA_KEYS = {"F": "orbit/fly", "R": "reset view", "C": "fit scene"}
#: pointer buttons (jupyter_rfb numbering: 1 left, 2 right, 3 middle)
LEFT, RIGHT, MIDDLE = 1, 2, 3


class CameraController:
    """Orbit (drag rotates around the target, scroll zooms) or fly (drag looks, keys move) a Camera.

    Until the user moves it, `camera()` returns the scene's own Camera unchanged, so a viewer
    frame and `guaca render` of the same scene see exactly the same view. `bounds` (world-space
    min and max corners of the scene) is what "fit" frames.
    """

    ORBIT_SPEED = 0.005  # radians per pixel dragged
    MAX_PITCH = math.radians(89.0)
    MOVE_SPEED = 0.5  # held-key movement: the starting eye-to-target distance per second
    MAX_STEP_S = 0.25  # a held key moves at most this many seconds' worth per frame (a stalled frame does not jump)
    FIT_MARGIN = 1.1  # fit leaves this much room around the scene's bounding sphere

    def __init__(self, camera: Camera, bounds: tuple[np.ndarray, np.ndarray] | None = None):
        self.initial = camera
        self.bounds = bounds
        self.mode = "orbit"
        self.reset()
        self.speed = max(self.distance, 1e-3) * self.MOVE_SPEED

    def reset(self) -> None:
        """Back to the scene's own camera (`camera()` returns it unchanged again)."""
        self._moved = False
        self.far = self.initial.far
        eye = np.asarray(self.initial.position, dtype=np.float64)
        target = np.asarray(self.initial.target, dtype=np.float64)
        offset = eye - target
        self.target = target
        self.distance = float(np.linalg.norm(offset))
        self.yaw = math.atan2(offset[0], offset[2])
        self.pitch = math.asin(max(-1.0, min(1.0, offset[1] / self.distance)))

    @property
    def eye(self) -> np.ndarray:
        """Camera position from target, yaw, pitch and distance."""
        cp = math.cos(self.pitch)
        offset = np.array([math.sin(self.yaw) * cp, math.sin(self.pitch), math.cos(self.yaw) * cp])
        return self.target + offset * self.distance

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit forward, right and up vectors of the current view (world space)."""
        f = self.target - self.eye
        f /= np.linalg.norm(f)
        r = np.cross(f, (0.0, 1.0, 0.0))
        r /= max(np.linalg.norm(r), 1e-12)
        return f, r, np.cross(r, f)

    def toggle_mode(self) -> str:
        """Switch between orbit and fly; returns the new mode."""
        self.mode = "fly" if self.mode == "orbit" else "orbit"
        return self.mode

    def drag(self, dx: float, dy: float) -> None:
        """Mouse drag by (dx, dy) pixels: orbit around the target, or turn the view in fly mode."""
        self._moved = True
        eye = self.eye
        self.yaw -= dx * self.ORBIT_SPEED
        self.pitch = max(-self.MAX_PITCH, min(self.MAX_PITCH, self.pitch + dy * self.ORBIT_SPEED))
        if self.mode == "fly":  # fly mode turns around the eye: move the target so the eye stays put
            self.target = self.target + (eye - self.eye)

    def pan(self, dx: float, dy: float, viewport_height: int) -> None:
        """Slide eye and target sideways so the point at the target follows a drag of (dx, dy) pixels (y down)."""
        self._moved = True
        _, right, up = self.axes()
        # world units per pixel at the target's depth: the view's height there over the viewport's
        per_pixel = 2.0 * self.distance * math.tan(math.radians(self.initial.fov_y) / 2.0) / max(viewport_height, 1)
        self.target = self.target + (-dx * right + dy * up) * per_pixel

    def pointer_drag(
        self, dx: float, dy: float, button: int, modifiers: Iterable[str] = (), viewport_height: int = 1
    ) -> None:
        """A drag with `button` held: left orbits (fly: looks), middle, right or shift+left pans."""
        if button in (MIDDLE, RIGHT) or (button == LEFT and "Shift" in modifiers):
            self.pan(dx, dy, viewport_height)
        elif button == LEFT:
            self.drag(dx, dy)

    def zoom(self, steps: float) -> None:
        """Scroll: move towards (positive steps) or away from the target."""
        self._moved = True
        self.distance = max(self.initial.near * 2.0, self.distance * 0.9**steps)

    def move(self, forward: float, right: float, up: float) -> None:
        """Translate eye and target along the view's forward and right axes and the world's up (scene units)."""
        self._moved = True
        f, r, _ = self.axes()
        self.target = self.target + f * forward + r * right + np.array([0.0, up, 0.0])

    def advance(self, held: Iterable[str], dt: float) -> bool:
        """Move for `dt` seconds along the held MOVE_KEYS at `speed`; returns whether anything moved."""
        direction = np.zeros(3)
        for name in held:
            direction += MOVE_KEYS.get(name, (0, 0, 0))
        if not direction.any() or dt <= 0.0:
            return False
        step = self.speed * min(dt, self.MAX_STEP_S)
        self.move(*(direction * step))
        return True

    def fit(self) -> bool:
        """Frame the scene's bounds from the current direction (returns False without bounds, or empty ones)."""
        if self.bounds is None:
            return False
        lo, hi = (np.asarray(b, dtype=np.float64) for b in self.bounds)
        if not (hi > lo).any():  # nothing drawn (scene_bounds gives a point): nothing to frame
            return False
        radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-6)
        half_fov = math.radians(self.initial.fov_y) / 2.0  # the vertical half-angle (the narrower one in landscape)
        self._moved = True
        self.target = (lo + hi) / 2.0
        self.distance = max(radius * self.FIT_MARGIN / math.sin(half_fov), self.initial.near * 2.0)
        self.far = max(self.initial.far, (self.distance + radius) * 1.5)  # the whole sphere stays in front of far
        return True

    def key(self, name: str) -> bool:
        """React to a CAMERA_KEYS key; returns whether `name` was one."""
        if name == "F":
            self.toggle_mode()
        elif name == "R":
            self.reset()
        elif name == "C":
            self.fit()
        else:
            return False
        return True

    def camera(self) -> Camera:
        """The Camera to render with (the scene's own until moved)."""
        if not self._moved:
            return self.initial
        return replace(
            self.initial,
            position=tuple(self.eye.tolist()),
            target=tuple(self.target.tolist()),
            up=(0.0, 1.0, 0.0),
            far=self.far,
        )
