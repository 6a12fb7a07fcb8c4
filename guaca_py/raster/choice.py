"""`transparency.raster`: which rasterizer produces a draw's transparent fragments, and `auto`'s rule."""

from __future__ import annotations

import numpy as np

from ..pipeline.settings import Setting

RASTER_SETTING = Setting(
    (str,),
    "auto",
    "rasterizer of transparent draws: 'hardware' (fragment shader), 'compute' (compute kernels, "
    "raster/compute_raster.py) or 'auto' (compute for small triangles on GPUs, see docs/raster.md)",
    choices=("hardware", "compute", "auto"),
)

RASTER_ORDER_SETTING = Setting(
    (str,),
    "auto",
    "order in which the compute rasterizer takes a draw's triangles: 'depth' (front to back with early "
    "termination, back to front without), 'mesh' (index order), 'tile' (screen tiles, by depth within "
    "each) or 'auto' (the method's; docs/raster.md)",
    choices=("auto", "depth", "mesh", "tile"),
)

# `auto` takes the compute rasterizer for a draw whose visible triangles cover at most this many
# pixels on average (estimated from a fixed sample). On the H100 (benchmarks/results/h100/
# raster_sweep/; docs/decisions.md, 2026-11-23 "raster: auto") compute stored fragments 4-15x faster
# than the hardware at every size measured, 0.5 to 16384 px², and Table 1's dragons and Sponza 2.8-5x: the bound is
# the largest size measured, beyond which nothing is known.
AUTO_MAX_MEAN_AREA_PX = 16384.0
SAMPLE_TRIANGLES = 256  # triangles per mesh sampled for the estimate (fixed seed, cached)

SHAPES_PER_MESH = 256  # projected_shape results kept per mesh (a moving camera or node makes every key new)


def auto_rule() -> str:
    """The `auto` rule in words (printed by `guaca info` and reported with every frame)."""
    return (
        f"compute where the device is a GPU and a draw's mean projected triangle area is at most "
        f"{AUTO_MAX_MEAN_AREA_PX:g} px², hardware otherwise"
    )


# Frames of more pixels than this take their triangles in tile order even with early termination.
# On the H100 (presort_lf_et, docs/decisions.md, 2026-11-27 "tile order for large frames"), depth
# order sweeps the whole frame at once and its list walks and composite read a pool larger than the
# GPU's caches and translation reach: at 4096² tile order took hairball_v1 from 482 to 41 ms and the
# dragons from 35.4 to 12.5 ms (composite 143 -> 5.7 and 10.5 -> 1.2 ms), while at 1024² depth order
# stays ahead (hairball_v1 5.2 against 6.4 ms: early termination culls more) and 2048² is near even.
LARGE_FRAME_PIXELS = 2048 * 2048


def auto_order(early_termination: bool, pixels: int) -> str:
    """The triangle order `raster_order: auto` takes for a method and a frame of `pixels` pixels."""
    if early_termination and pixels <= LARGE_FRAME_PIXELS:
        return "depth"
    return "tile"


def large_tile_frame(method, pixels: int) -> bool:
    """Whether the compute rasterizer takes a frame of `pixels` in tile order with the large frames' buckets
    (a screen tile's nodes then lie together in the pool: the composite reads them in strips)."""
    return pixels > LARGE_FRAME_PIXELS and method.raster_order(pixels) == "tile"


def order_rule() -> str:
    """The `raster_order: auto` rule in words (printed by `guaca info`)."""
    return (
        f"depth (front to back) for methods with early termination in frames of at most "
        f"{LARGE_FRAME_PIXELS:,} pixels (2048²), tile (screen tiles, by depth within each) otherwise"
    )


def device_rule(caps) -> str:
    """What `auto` does on this device, and why (for `guaca info`)."""
    if caps.software:
        return "hardware for every draw: " + auto_choice(True, 0.0)[1]
    return auto_rule()


def _sample(mesh) -> tuple[np.ndarray, np.ndarray | None]:
    """A fixed sample of the mesh's triangles: corners as homogeneous object-space points (k·3, 4) and
    their vertex normals (k·3, 3; None for a mesh without normals), kept with the mesh's arrays."""
    return mesh.derived("raster_sample", _draw_sample)


def _draw_sample(mesh) -> tuple[np.ndarray, np.ndarray | None]:
    idx = np.asarray(mesh.indices).reshape(-1, 3)
    if len(idx) > SAMPLE_TRIANGLES:
        idx = idx[np.random.default_rng(0).choice(len(idx), SAMPLE_TRIANGLES, replace=False)]
    corners = np.asarray(mesh.positions, dtype=np.float64)[idx.ravel()]
    points = np.hstack([corners, np.ones((len(corners), 1))])
    normals = getattr(mesh, "normals", None)
    normals = None if normals is None else np.asarray(normals, dtype=np.float64)[idx.ravel()]
    return points, normals


def _on_screen(mesh, world: np.ndarray, view_projection: np.ndarray, width: int, height: int):
    """The sampled triangles in front of the near plane and on screen: (corners in pixels (n, 3, 2), their
    row indices into the sample)."""
    points, _ = _sample(mesh)
    clip = (points @ (view_projection @ world).T).reshape(-1, 3, 4)
    keep = (clip[..., 2] > -clip[..., 3]).all(axis=1)  # all corners in front of the near plane (z > -w)
    half = 0.5 * np.array([width, height])
    xy = clip[..., :2] / np.where(keep[:, None, None], clip[..., 3:4], 1.0) * half + half
    lo, hi = xy.min(axis=1), xy.max(axis=1)
    keep &= ((hi >= 0) & (lo <= (width, height))).all(axis=1)
    rows = np.flatnonzero(keep)
    return xy[rows], rows


def projected_shape(
    mesh, world: np.ndarray, view_projection: np.ndarray, width: int, height: int, turn: bool = True
) -> tuple[float, float]:
    """(mean area in px², normal turn in radians per px) of the mesh's sampled triangles in front of the
    near plane and on screen ((0, 0): none), from one projection of the sample, cached per draw and camera.

    The turn is the median over those triangles of the largest angle between two corners' normals over
    the length of their edge in pixels (0 for a mesh without normals): shading varies within a pixel
    where it is large. `turn=False`: the area alone (the turn reads 0), as the rasterizer's choice per draw
    needs, without the normals' work."""
    # kept with the mesh's arrays (MeshData.derived), so a mesh replaced or gone takes its entries along
    shapes = mesh.derived("projected_shapes", lambda _mesh: {})
    key = (world.tobytes(), view_projection.tobytes(), width, height, turn)
    hit = shapes.get(key)
    if hit is not None:  # the common case: an unchanged draw and camera
        return hit
    xy, rows = _on_screen(mesh, world, view_projection, width, height)
    area = turned = 0.0
    if len(xy):
        e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
        area = float(np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).mean()) * 0.5
        _, normals = _sample(mesh)
        if turn and normals is not None:
            n = normals.reshape(-1, 3, 3)[rows] @ np.linalg.inv(world[:3, :3])  # the normal matrix, on row vectors
            n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-30)
            turns = []
            for a, b in ((0, 1), (0, 2), (1, 2)):
                angle = np.arccos(np.clip((n[:, a] * n[:, b]).sum(axis=1), -1.0, 1.0))
                turns.append(angle / np.maximum(np.hypot(*(xy[:, b] - xy[:, a]).T), 1e-3))
            turned = float(np.median(np.max(turns, axis=0)))
    if len(shapes) >= SHAPES_PER_MESH:  # bounded: a moving camera or node makes every key new
        shapes.clear()
    shapes[key] = (area, turned)
    return area, turned


def mean_projected_area(mesh, world: np.ndarray, view_projection: np.ndarray, width: int, height: int) -> float:
    """Mean screen area in px² of the sampled triangles in front of the near plane and on screen (0: none)."""
    return projected_shape(mesh, world, view_projection, width, height, turn=False)[0]


def compute_kernels_draw(raster: str | None, caps) -> bool:
    """Whether the compute rasterizer makes (most of) the transparent fragments: `compute`, or `auto` on a GPU."""
    return raster == "compute" or (raster == "auto" and not caps.software)


def auto_choice(software: bool, mean_area: float) -> tuple[str, str]:
    """(rasterizer, reason) of `auto` for one draw."""
    if software:
        return "hardware", "software rasterizer: compute kernels would run on the same CPU cores"
    if mean_area <= AUTO_MAX_MEAN_AREA_PX:
        return "compute", f"mean projected triangle area {mean_area:.1f} px² <= {AUTO_MAX_MEAN_AREA_PX:g}"
    return "hardware", f"mean projected triangle area {mean_area:.1f} px² > {AUTO_MAX_MEAN_AREA_PX:g}"
