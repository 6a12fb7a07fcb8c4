"""Pack scene lights into the std430 layout the shaders read (see shading/lighting.glsl.j2)."""
from __future__ import annotations

import numpy as np

from ..scene.graph import Light

LIGHT_TYPE_CODE = {"point": 0.0, "spot": 1.0, "directional": 2.0}
FLOATS_PER_LIGHT = 16


def pack_lights(lights: list[Light]) -> np.ndarray:
    """(n, 16) float32 rows: position+range, color*intensity+type, direction+cos outer, cos inner."""
    out = np.zeros((max(len(lights), 1), FLOATS_PER_LIGHT), dtype=np.float32)
    if not lights:
        return out
    n = len(lights)
    # column-wise: thousands of lights are packed every frame, a per-light numpy loop cost ~13 ms at 4096
    d = np.array([l.direction for l in lights], dtype=np.float64).reshape(n, 3)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    d = d / np.where(norm > 0, norm, 1.0)
    outer = np.array([l.outer_angle_deg for l in lights], dtype=np.float64)
    inner = np.minimum(np.array([l.inner_angle_deg for l in lights], dtype=np.float64), outer)
    out[:n, 0:3] = np.array([l.position for l in lights], dtype=np.float64).reshape(n, 3)
    out[:n, 3] = [l.radius for l in lights]
    out[:n, 4:7] = np.array([l.color for l in lights], dtype=np.float64).reshape(n, 3) * \
        np.array([l.intensity for l in lights], dtype=np.float64)[:, None]
    out[:n, 7] = [LIGHT_TYPE_CODE[l.type] for l in lights]
    out[:n, 8:11] = d
    out[:n, 11] = np.cos(np.radians(outer))
    out[:n, 12] = np.cos(np.radians(inner))
    return out


def frustum_planes(view_projection: np.ndarray) -> np.ndarray:
    """Six inward-facing planes (a, b, c, d), normalized, of a GL view-projection matrix."""
    m = view_projection
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def visible_lights(lights: list[Light], view_projection: np.ndarray) -> list[Light]:
    """Lights whose volume (range sphere) can reach the view frustum; directional lights always."""
    if not lights:
        return []
    planes = frustum_planes(view_projection)
    # all lights at once: a Python loop over 4096 lights cost ~60 ms a frame, leaving the GPU idle
    p = np.ones((len(lights), 4))
    p[:, :3] = [l.position for l in lights]
    radius = np.array([l.radius for l in lights], dtype=np.float64)
    inside = np.all(p @ planes.T >= -radius[:, None], axis=1)
    return [l for l, keep in zip(lights, inside) if keep or l.type == "directional"]
