"""Orbit and fly camera control on top of the scene's look-at Camera."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..scene.graph import Camera


class CameraController:
    """Orbit (drag rotates around the target, scroll zooms) or fly (drag looks, keys move) a Camera.

    Until the user moves it, `camera()` returns the scene's own Camera unchanged, so a viewer
    frame and `guaca render` of the same scene see exactly the same view.
    """

    ORBIT_SPEED = 0.005  # radians per pixel dragged
    MAX_PITCH = math.radians(89.0)

    def __init__(self, camera: Camera):
        self.initial = camera
        self.mode = "orbit"
        self._moved = False
        eye = np.asarray(camera.position, dtype=np.float64)
        target = np.asarray(camera.target, dtype=np.float64)
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

    def toggle_mode(self) -> str:
        """Switch between orbit and fly; returns the new mode."""
        self.mode = "fly" if self.mode == "orbit" else "orbit"
        return self.mode

    def drag(self, dx: float, dy: float) -> None:
        """Mouse drag by (dx, dy) pixels: orbit around the target, or turn the view in fly mode."""
        self._moved = True
        if self.mode == "orbit":
            self.yaw -= dx * self.ORBIT_SPEED
            self.pitch = max(-self.MAX_PITCH, min(self.MAX_PITCH, self.pitch + dy * self.ORBIT_SPEED))
            return
        eye = self.eye
        self.yaw -= dx * self.ORBIT_SPEED
        self.pitch = max(-self.MAX_PITCH, min(self.MAX_PITCH, self.pitch + dy * self.ORBIT_SPEED))
        # fly mode turns around the eye: move the target so the eye stays put
        self.target = self.target + (eye - self.eye)

    def zoom(self, steps: float) -> None:
        """Scroll: move towards (positive steps) or away from the target."""
        self._moved = True
        self.distance = max(self.initial.near * 2.0, self.distance * 0.9**steps)

    def move(self, forward: float, right: float, up: float) -> None:
        """Fly: translate eye and target along the view axes (units of the scene)."""
        self._moved = True
        f = self.target - self.eye
        f /= np.linalg.norm(f)
        r = np.cross(f, np.asarray(self.initial.up, dtype=np.float64))
        r /= max(np.linalg.norm(r), 1e-12)
        self.target = self.target + f * forward + r * right + np.array([0.0, up, 0.0])

    def camera(self) -> Camera:
        """The Camera to render with (the scene's own until moved)."""
        if not self._moved:
            return self.initial
        return replace(
            self.initial,
            position=tuple(self.eye.tolist()),
            target=tuple(self.target.tolist()),
            up=(0.0, 1.0, 0.0),
        )
