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

# `auto` takes the compute rasterizer for a draw whose visible triangles cover at most this many
# pixels on average (estimated from a fixed sample). Provisional: benchmarks/raster_sweep.py
# measures the crossing point of both rasterizers on a device; set it from the H100's chart.
AUTO_MAX_MEAN_AREA_PX = 64.0
SAMPLE_TRIANGLES = 1024  # triangles per mesh sampled for the estimate (fixed seed, cached)


def auto_rule() -> str:
    """The `auto` rule in words (printed by `guaca info` and reported with every frame)."""
    return (
        f"compute where the device is a GPU and a draw's mean projected triangle area is at most "
        f"{AUTO_MAX_MEAN_AREA_PX:g} px², hardware otherwise"
    )


def device_rule(caps) -> str:
    """What `auto` does on this device, and why (for `guaca info`)."""
    if caps.software:
        return "hardware for every draw: " + auto_choice(True, 0.0)[1]
    return auto_rule()


def _sample(mesh) -> np.ndarray:
    """A fixed sample of the mesh's triangles as object-space corner positions (k, 3, 3), cached.

    The sample is kept on the mesh itself (while its arrays stay the same objects), so it goes
    away with the mesh: a module-level table would keep every mesh ever drawn alive.
    """
    arrays = (id(mesh.positions), id(mesh.indices))
    hit = mesh.__dict__.get("_gua_raster_sample")
    if hit is not None and hit[0] == arrays:
        return hit[1]
    idx = np.asarray(mesh.indices).reshape(-1, 3)
    if len(idx) > SAMPLE_TRIANGLES:
        idx = idx[np.random.default_rng(0).choice(len(idx), SAMPLE_TRIANGLES, replace=False)]
    tris = np.asarray(mesh.positions, dtype=np.float64)[idx]
    mesh.__dict__["_gua_raster_sample"] = (arrays, tris)
    return tris


def mean_projected_area(mesh, world: np.ndarray, view_projection: np.ndarray, width: int, height: int) -> float:
    """Mean screen area in px² of the sampled triangles in front of the near plane and on screen (0: none)."""
    tris = _sample(mesh)
    if not len(tris):
        return 0.0
    m = view_projection @ world
    p = tris @ m[:3, :3].T + m[:3, 3]
    w = tris @ m[3, :3] + m[3, 3]
    z = p[..., 2]
    front = np.all(z > -w, axis=1)  # all corners in front of the near plane
    if not front.any():
        return 0.0
    xy = p[front][..., :2] / w[front][..., None]
    xy = (xy + 1.0) * 0.5 * np.array([width, height])
    on_screen = (
        (xy[..., 0].max(axis=1) >= 0)
        & (xy[..., 0].min(axis=1) <= width)
        & (xy[..., 1].max(axis=1) >= 0)
        & (xy[..., 1].min(axis=1) <= height)
    )
    if not on_screen.any():
        return 0.0
    a, b, c = xy[on_screen, 0], xy[on_screen, 1], xy[on_screen, 2]
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    return float(area.mean())


def auto_choice(software: bool, mean_area: float) -> tuple[str, str]:
    """(rasterizer, reason) of `auto` for one draw."""
    if software:
        return "hardware", "software rasterizer: compute kernels would run on the same CPU cores"
    if mean_area <= AUTO_MAX_MEAN_AREA_PX:
        return "compute", f"mean projected triangle area {mean_area:.1f} px² <= {AUTO_MAX_MEAN_AREA_PX:g}"
    return "hardware", f"mean projected triangle area {mean_area:.1f} px² > {AUTO_MAX_MEAN_AREA_PX:g}"
