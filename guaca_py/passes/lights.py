"""Pack scene lights into the std430 layout the shaders read (see shading/lighting.glsl.j2)."""
from __future__ import annotations

import math

import numpy as np

from ..scene.graph import Light

LIGHT_TYPE_CODE = {"point": 0.0, "spot": 1.0, "directional": 2.0}
FLOATS_PER_LIGHT = 16


def pack_lights(lights: list[Light]) -> np.ndarray:
    """(n, 16) float32 rows: position+range, color*intensity+type, direction+cos outer, cos inner."""
    out = np.zeros((max(len(lights), 1), FLOATS_PER_LIGHT), dtype=np.float32)
    for i, l in enumerate(lights):
        d = np.asarray(l.direction, dtype=np.float64)
        d = d / (np.linalg.norm(d) or 1.0)
        out[i, 0:3], out[i, 3] = l.position, l.radius
        out[i, 4:7] = np.asarray(l.color, dtype=np.float64) * l.intensity
        out[i, 7] = LIGHT_TYPE_CODE[l.type]
        out[i, 8:11], out[i, 11] = d, math.cos(math.radians(l.outer_angle_deg))
        out[i, 12] = math.cos(math.radians(min(l.inner_angle_deg, l.outer_angle_deg)))
    return out


def frustum_planes(view_projection: np.ndarray) -> np.ndarray:
    """Six inward-facing planes (a, b, c, d), normalized, of a GL view-projection matrix."""
    m = view_projection
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def visible_lights(lights: list[Light], view_projection: np.ndarray) -> list[Light]:
    """Lights whose volume (range sphere) can reach the view frustum; directional lights always."""
    planes = frustum_planes(view_projection)
    out = []
    for l in lights:
        if l.type == "directional":
            out.append(l)
            continue
        p = np.append(np.asarray(l.position, dtype=np.float64), 1.0)
        if np.all(planes @ p >= -l.radius):
            out.append(l)
    return out
