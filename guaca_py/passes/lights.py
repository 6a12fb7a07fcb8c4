"""Pack scene lights into the std430 layout the shaders read (see shading/lighting.glsl.j2)."""

from __future__ import annotations

import numpy as np

from ..scene.graph import Light

LIGHT_TYPE_CODE = {"point": 0.0, "spot": 1.0, "directional": 2.0, "ambient": 3.0}
#: lights without a position reach every tile: light culling gives them every tile's bit
EVERYWHERE_TYPES = ("directional", "ambient")
FLOATS_PER_LIGHT = 16


def light_table(lights: list[Light]) -> np.ndarray:
    """(n, 16) float64 rows in the packed layout: position+range, color*intensity+type, direction+cos outer, cos inner.

    Gathered once per frame: culling and ordering read its columns, the upload is a float32 cast
    of the rows they select (a per-light loop cost ~75 ms a frame at 4096 lights).
    """
    n = len(lights)
    out = np.zeros((n, FLOATS_PER_LIGHT))
    if not n:
        return out
    d = np.array([l.direction for l in lights], dtype=np.float64).reshape(n, 3)
    big = np.max(np.abs(d), axis=1, keepdims=True)
    d = d / np.where(big > 0, big, 1.0)  # scaled first: the norm of [1e300, -1e300, 0] would overflow to inf
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    outer = np.array([l.outer_angle_deg for l in lights], dtype=np.float64)
    inner = np.minimum(np.array([l.inner_angle_deg for l in lights], dtype=np.float64), outer)
    out[:, 0:3] = np.array([l.position for l in lights], dtype=np.float64).reshape(n, 3)
    out[:, 3] = [l.radius for l in lights]
    out[:, 4:7] = (
        np.array([l.color for l in lights], dtype=np.float64).reshape(n, 3)
        * np.array([l.intensity for l in lights], dtype=np.float64)[:, None]
    )
    out[:, 7] = [LIGHT_TYPE_CODE[l.type] for l in lights]
    out[:, 8:11] = d / np.where(norm > 0, norm, 1.0)
    out[:, 11] = np.cos(np.radians(outer))
    out[:, 12] = np.cos(np.radians(inner))
    return out


def pack_lights(table: np.ndarray) -> np.ndarray:
    """The float32 upload of light_table rows (one zero row when there are none: buffers are never empty)."""
    return table.astype(np.float32) if len(table) else np.zeros((1, FLOATS_PER_LIGHT), dtype=np.float32)


def frustum_planes(view_projection: np.ndarray) -> np.ndarray:
    """Six inward-facing planes (a, b, c, d), normalized, of a GL view-projection matrix."""
    m = view_projection
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def reaches_everywhere(table: np.ndarray) -> np.ndarray:
    """Per light_table row: a light without a position (directional, ambient), which reaches every tile."""
    return np.isin(table[:, 7], [LIGHT_TYPE_CODE[t] for t in EVERYWHERE_TYPES])


def visible_mask(table: np.ndarray, view_projection: np.ndarray) -> np.ndarray:
    """Per light_table row: can its volume (range sphere) reach the view frustum; directional and ambient always."""
    p = np.ones((len(table), 4))
    p[:, :3] = table[:, 0:3]
    inside = np.all(p @ frustum_planes(view_projection).T >= -table[:, 3:4], axis=1)
    return inside | reaches_everywhere(table)
