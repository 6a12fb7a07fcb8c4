"""A camera and lights for models that bring none: framing, the camera-sees-the-model check, the default rig.

A glTF or mesh file, or a trimesh scene, gets what a scene file would spell out: its own camera
when it has one that sees the model (else one framing the model, with a `SceneWarning`), and
the default light rig, as these files bring no lights.
"""

from __future__ import annotations

import math

import numpy as np

from .nodes import Camera, Light, Node, scene_bounds
from .trimesh_scene import warn_scene

#: where the default camera looks from, relative to the model's centre (above, right, in front)
_VIEW_DIRECTION = np.array([0.45, 0.35, 1.0]) / np.linalg.norm([0.45, 0.35, 1.0])
#: the default rig: key (from above the camera's left shoulder), fill (from the right, low) and ambient
KEY_INTENSITY, FILL_INTENSITY, AMBIENT_INTENSITY = 2.5, 0.6, 0.15


def framing_camera(lo: np.ndarray, hi: np.ndarray, fov_y: float = 45.0) -> Camera:
    """A camera that sees the whole box [lo, hi] (its bounding sphere) from above, right and front."""
    center = (np.asarray(lo, dtype=np.float64) + np.asarray(hi, dtype=np.float64)) / 2.0
    radius = max(float(np.linalg.norm(np.subtract(hi, lo))) / 2.0, 1e-3)
    dist = radius / math.sin(math.radians(fov_y) / 2.0) * 1.05
    eye = center + _VIEW_DIRECTION * dist
    return Camera(
        position=tuple(eye.tolist()),
        target=tuple(center.tolist()),
        up=(0.0, 1.0, 0.0),
        fov_y=fov_y,
        near=max(dist - 1.5 * radius, dist * 1e-3),
        far=dist + 1.5 * radius,
    )


def _unit(v) -> tuple[float, float, float]:
    v = np.asarray(v, dtype=np.float64)
    return tuple((v / np.linalg.norm(v)).tolist())


def default_lights(camera: Camera) -> list[Light]:
    """The rig for files without lights: a key and a fill directional light and an ambient term.

    The key comes from above and behind the camera's left shoulder, the fill from its right and
    below the key, weaker; the ambient term lifts faces that neither reaches, so no face turned
    away from both is pure black (light travelling the other way reaches it only through it).
    """
    view = np.subtract(camera.target, camera.position)
    view = view / np.linalg.norm(view)
    up = np.asarray(camera.up, dtype=np.float64)
    right = np.cross(view, up)
    norm = np.linalg.norm(right)
    right = right / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
    world_up = np.array([0.0, 1.0, 0.0])
    key = view + np.array([0.35, -0.9, 0.0])  # as the single light these files had before
    fill = view - 0.8 * right - 0.3 * world_up
    return [
        Light(type="directional", direction=_unit(key), intensity=KEY_INTENSITY),
        Light(type="directional", direction=_unit(fill), color=(0.9, 0.95, 1.0), intensity=FILL_INTENSITY),
        Light(type="ambient", intensity=AMBIENT_INTENSITY),
    ]


def camera_sees(camera: Camera, lo: np.ndarray, hi: np.ndarray, aspect: float = 1.0) -> bool:
    """False when the box [lo, hi] lies wholly outside the camera's frustum (behind it, beside it, past far).

    A box is outside when all eight corners are outside one of the six planes: a conservative
    test (a box near a frustum corner may pass and still be unseen), so only a camera that
    certainly sees nothing of the model fails it.
    """
    vp = camera.projection_matrix(aspect) @ camera.view_matrix()
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    clip = corners @ vp.T
    w = clip[:, 3]
    for axis in range(3):
        if np.all(clip[:, axis] > w) or np.all(clip[:, axis] < -w):
            return False
    return True


def camera_and_lights(nodes: list[Node], camera: Camera | None, label: str) -> tuple[Camera, list[Light]]:
    """The file's camera (one framing `nodes` when None or when it sees none of them, with a warning) and the rig."""
    lo, hi = scene_bounds(nodes)
    if camera is not None and not camera_sees(camera, lo, hi):
        eye = ", ".join(f"{c:.3g}" for c in camera.position)
        warn_scene(
            f"{label}: its camera (at {eye}) sees none of the model (bounds "
            f"{np.round(lo, 3).tolist()} to {np.round(hi, 3).tolist()}); a camera framing the model is used instead"
        )
        camera = None
    camera = camera or framing_camera(lo, hi)
    return camera, default_lights(camera)
