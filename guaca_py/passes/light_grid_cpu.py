"""Exact float64 CPU answer to "which light volumes overlap which tile frusta", to check the light grid.

A tile's frustum is the part of the view frustum (near to far) that projects into the tile's
on-screen pixel rectangle. A point light's volume is the open ball of its range; a spot light's is
that ball cut by the cone of its outer half-angle (the set where the shading is non-zero); a
directional or ambient light reaches every tile. Sphere tests are exact (distance from the centre to the
frustum polyhedron); spot tests are exact except that the minimum over the cone's rim angle is
taken over `cone_samples` rays, which can only under-report an overlap, never invent one.
"""

from __future__ import annotations

import math

import numpy as np

from ..pipeline.resources import unpack_grid
from ..scene.graph import Light
from .lights import EVERYWHERE_TYPES

# corners 0-3 on the near plane, 4-7 on the far plane, counter-clockwise seen from the eye
_FACES = np.array([[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]])
_LIGHT_CHUNK = 32


def grid_shape(width: int, height: int, tile: int) -> tuple[int, int]:
    """(tiles across, tiles down) covering a width x height image."""
    return -(-width // tile), -(-height // tile)


def tile_frusta(view: np.ndarray, projection: np.ndarray, width: int, height: int, tile: int) -> np.ndarray:
    """World-space corners (th, tw, 8, 3) of every tile frustum; tile row 0 is the bottom (GL window y)."""
    tw, th = grid_shape(width, height, tile)
    inv = np.linalg.inv(np.asarray(projection, np.float64) @ np.asarray(view, np.float64))
    x0 = np.arange(tw) * tile
    y0 = np.arange(th) * tile
    x1, y1 = np.minimum(x0 + tile, width), np.minimum(y0 + tile, height)
    xs = np.stack([x0, x1, x1, x0], axis=-1) / width * 2.0 - 1.0  # (tw, 4)
    ys = np.stack([y0, y0, y1, y1], axis=-1) / height * 2.0 - 1.0  # (th, 4)
    out = np.empty((th, tw, 8, 3))
    for k, z in enumerate((-1.0, 1.0)):
        ndc = np.stack(np.broadcast_arrays(xs[None, :, :], ys[:, None, :], z, 1.0), axis=-1)  # (th, tw, 4, 4)
        w = ndc @ inv.T
        out[:, :, 4 * k : 4 * k + 4] = w[..., :3] / w[..., 3:4]
    return out


def _planes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals (T, 6, 3) and offsets (T, 6) of frusta given as corners (T, 8, 3)."""
    quads = corners[:, _FACES]  # (T, 6, 4, 3)
    n = np.cross(quads[:, :, 1] - quads[:, :, 0], quads[:, :, 3] - quads[:, :, 0])
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    centre = corners.mean(axis=1)[:, None, :]
    flip = np.einsum("tfk,tfk->tf", n, centre - quads[:, :, 0]) > 0  # make the normals point out
    n[flip] *= -1.0
    return n, -np.einsum("tfk,tfk->tf", n, quads[:, :, 0])


def _closest_on_segments(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(
        np.einsum("...k,...k->...", q - a, ab) / np.maximum(np.einsum("...k,...k->...", ab, ab), 1e-300), 0.0, 1.0
    )
    return a + t[..., None] * ab


def closest_points(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Closest point (L, T, 3) of each convex frustum (T, 8, 3) to each point (L, 3); the point itself inside."""
    n, d = _planes(corners)
    quads = corners[:, _FACES]  # (T, 6, 4, 3)
    q = points[:, None, None, :]  # (L, 1, 1, 3)
    sd = np.einsum("tfk,lk->ltf", n, points) + d[None]  # (L, T, 6)
    inside = np.all(sd <= 0.0, axis=-1)
    proj = q - sd[..., None] * n[None]  # (L, T, 6, 3) on each face plane
    a, b = quads, np.roll(quads, -1, axis=2)  # face edges (T, 6, 4, 3)
    centre = quads.mean(axis=2, keepdims=True)
    m = np.cross(b - a, n[:, :, None, :])  # in-plane edge normals
    m *= np.where(np.einsum("tfek,tfek->tfe", m, centre - a) < 0, -1.0, 1.0)[..., None]  # pointing inward
    in_face = np.all(np.einsum("tfek,ltfek->ltfe", m, proj[:, :, :, None, :] - a[None]) >= 0.0, axis=-1)
    on_edges = _closest_on_segments(q[..., None, :], a[None], b[None])  # (L, T, 6, 4, 3)
    e_dist = np.linalg.norm(on_edges - q[..., None, :], axis=-1)
    best_edge = np.take_along_axis(on_edges, e_dist.argmin(axis=-1)[..., None, None], axis=-2)[..., 0, :]
    cand = np.where(in_face[..., None], proj, best_edge)  # (L, T, 6, 3)
    c_dist = np.linalg.norm(cand - q, axis=-1)
    best = np.take_along_axis(cand, c_dist.argmin(axis=-1)[..., None, None], axis=-2)[..., 0, :]
    return np.where(inside[..., None], points[:, None, :], best)


def _cone_rim_entry(
    apex: np.ndarray, axis: np.ndarray, half_angle: float, corners: np.ndarray, samples: int
) -> np.ndarray:
    """Smallest distance (T,) from the apex, along the cone's surface rays, at which a ray enters each frustum."""
    n, d = _planes(corners)  # (T, 6, 3), (T, 6)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    phi = np.arange(samples) * (2.0 * math.pi / samples)
    w = math.cos(half_angle) * axis[None] + math.sin(half_angle) * (
        np.cos(phi)[:, None] * e1[None] + np.sin(phi)[:, None] * e2[None]
    )  # (S, 3)
    num = -(np.einsum("tfk,k->tf", n, apex) + d)  # ray inside a plane while t*den <= num
    den = np.einsum("tfk,sk->tsf", n, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num[:, None, :] / den
    enter = np.where(den < 0, t, -np.inf).max(axis=-1)
    exit_ = np.where(den > 0, t, np.inf).min(axis=-1)
    parallel_out = np.any((den == 0) & (num[:, None, :] < 0), axis=-1)
    t0 = np.maximum(enter, 0.0)
    hit = (t0 <= exit_) & ~parallel_out
    return np.where(hit, t0, np.inf).min(axis=-1)


def exact_tile_lights(
    lights: list[Light],
    view: np.ndarray,
    projection: np.ndarray,
    width: int,
    height: int,
    tile: int,
    cone_samples: int = 1440,
) -> np.ndarray:
    """Bool (len(lights), th, tw): True where the light's volume overlaps the tile's frustum."""
    frusta = tile_frusta(view, projection, width, height, tile)
    th, tw = frusta.shape[:2]
    corners = frusta.reshape(-1, 8, 3)
    out = np.zeros((len(lights), th * tw), dtype=bool)
    pos = np.array([l.position for l in lights], dtype=np.float64).reshape(-1, 3)
    rad = np.array([l.radius for l in lights], dtype=np.float64)
    for s in range(0, len(lights), _LIGHT_CHUNK):
        cp = closest_points(pos[s : s + _LIGHT_CHUNK], corners)  # (l, T, 3)
        for k in range(cp.shape[0]):
            i = s + k
            light = lights[i]
            if light.type in EVERYWHERE_TYPES:
                out[i] = True
                continue
            off = cp[k] - pos[i]
            dist = np.linalg.norm(off, axis=-1)
            if light.type == "point":
                out[i] = dist < rad[i]
                continue
            axis = np.asarray(light.direction, dtype=np.float64)
            axis = axis / np.max(np.abs(axis))  # scaled first: a norm of 1e300 components overflows
            axis = axis / np.linalg.norm(axis)
            theta = math.radians(light.outer_angle_deg)
            in_cone = (dist == 0.0) | (off @ axis >= dist * math.cos(theta))
            hit = in_cone & (dist < rad[i])
            todo = ~in_cone & (dist < rad[i])  # nearest point outside the cone: the rim decides
            if np.any(todo):
                rim = _cone_rim_entry(pos[i], axis, theta, corners[todo], cone_samples)
                hit[todo] = rim < rad[i]
            out[i] = hit
    return out.reshape(len(lights), th, tw)


def compare_grids(exact: np.ndarray, assigned: np.ndarray) -> dict:
    """Missing (needed but not assigned) and extra (assigned but not needed) (light, tile) pairs."""
    missing = exact & ~assigned
    extra = assigned & ~exact
    return {
        "missing": int(missing.sum()),
        "extra": int(extra.sum()),
        "exact_pairs": int(exact.sum()),
        "assigned_pairs": int(assigned.sum()),
        "tiles": int(exact[0].size) if exact.size else 0,
        "lights_missing_tiles": [int(i) for i in np.flatnonzero(missing.reshape(len(missing), -1).any(axis=1))],
    }


__all__ = ["grid_shape", "tile_frusta", "closest_points", "exact_tile_lights", "unpack_grid", "compare_grids"]
