"""Ground truth for anti-aliased frames and errors against it (docs/antialiasing.md).

The reference of an anti-aliased frame is the exact method rendered at k times the resolution
and box filtered: every k x k block of point samples averaged into one pixel. Large references
are rendered in tiles (sub-frusta of the same camera), so k = 8 at 1024² needs no 8192² target.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import moderngl
import numpy as np

from ..pipeline.config import PipelineConfig, pipeline_from_text
from ..renderer import Renderer
from ..scene.graph import Camera, Scene


@dataclass
class TileCamera(Camera):
    """The camera of a full frame restricted to one tile of it: NDC [x0, x1] x [y0, y1] fills the target."""

    full_aspect: float = 1.0
    ndc: tuple[float, float, float, float] = (-1.0, 1.0, -1.0, 1.0)

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """The full frame's projection, then the tile's NDC window scaled to [-1, 1] (`aspect` is the tile's)."""
        x0, x1, y0, y1 = self.ndc
        sx, sy = 2.0 / (x1 - x0), 2.0 / (y1 - y0)
        crop = np.eye(4)
        crop[0, 0], crop[0, 3] = sx, -sx * 0.5 * (x0 + x1)
        crop[1, 1], crop[1, 3] = sy, -sy * 0.5 * (y0 + y1)
        return crop @ super().projection_matrix(self.full_aspect)


@dataclass
class Supersampled:
    """A box-filtered reference: mean colour per pixel and the spread of its sub-pixels."""

    image: np.ndarray  # (H, W, 3) float64 linear, row 0 at the top
    spread: np.ndarray  # (H, W) largest max-min over a channel of the k x k sub-pixels
    k: int
    tiles: int
    overflow: int = 0  # fragments the A-buffer dropped in any tile (pool at the device's limit): not exact there


def supersampled(
    renderer: Renderer, scene: Scene, width: int, height: int, k: int, tile_px: int = 2048, min_tile_px: int = 256
) -> Supersampled:
    """`renderer` (an exact method with linear output) at k x (width, height), box filtered to (width, height).

    Rendered in tiles of at most `tile_px` rendered pixels a side; a tile whose A-buffer overflowed (its pool
    at the device's limit) is rendered again as four, down to `min_tile_px`, and only that tile."""
    big_w, big_h = width * k, height * k
    nx, ny = -(-big_w // tile_px), -(-big_h // tile_px)
    # tiles hold whole output pixels, so each box filter reads one tile
    cols = np.linspace(0, width, nx + 1).round().astype(int)
    rows = np.linspace(0, height, ny + 1).round().astype(int)
    mean = np.zeros((height, width, 3))
    spread = np.zeros((height, width))
    overflow = tiles = 0
    todo = [
        (int(cols[tx]), int(cols[tx + 1]), int(rows[ty]), int(rows[ty + 1])) for ty in range(ny) for tx in range(nx)
    ]
    while todo:
        c0, c1, r0, r1 = todo.pop()
        if c1 <= c0 or r1 <= r0:
            continue
        ndc = (2.0 * c0 / width - 1.0, 2.0 * c1 / width - 1.0, 1.0 - 2.0 * r1 / height, 1.0 - 2.0 * r0 / height)
        cam = TileCamera(**dataclasses.asdict(scene.camera), full_aspect=width / height, ndc=ndc)
        frame = renderer.render(dataclasses.replace(scene, camera=cam), (c1 - c0) * k, (r1 - r0) * k)
        if frame.linear is None:
            raise ValueError("the supersampled reference needs a pipeline with linear output (pipelines/exact)")
        dropped = int(frame.stats.get("fragments", {}).get("overflow", 0))
        if dropped and max(c1 - c0, r1 - r0) * k >= 2 * min_tile_px:  # split the tile that overflowed
            cm, rm = (c0 + c1) // 2, (r0 + r1) // 2
            todo += [(c0, cm, r0, rm), (cm, c1, r0, rm), (c0, cm, rm, r1), (cm, c1, rm, r1)]
            continue
        mean[r0:r1, c0:c1], spread[r0:r1, c0:c1] = _block_mean_spread(frame.linear, k)
        overflow += dropped
        tiles += 1
    return Supersampled(mean, spread, k, tiles, overflow)


def _block_mean_spread(image: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean (float64) and largest channel max-min of every k x k block of an (H*k, W*k, 3) image.

    Summed over the k*k strided sub-images rather than reduced over a reshaped array: numpy reduces
    short inner axes slowly (a 2048² frame in 2x2 blocks: 2.2 s that way, 0.5 s this way; 8x8: 1.2 s, 0.4 s).
    """
    acc = lo = hi = None
    for i in range(k):
        for j in range(k):
            sub = image[i::k, j::k]
            if acc is None:
                acc, lo, hi = sub.astype(np.float64), sub.copy(), sub.copy()
            else:
                acc += sub
                np.minimum(lo, sub, out=lo)
                np.maximum(hi, sub, out=hi)
    return acc / (k * k), (hi.astype(np.float64) - lo).max(axis=-1)


def linear_pipeline(
    samples: int = 1, threshold: float = 0.999, light_culling: str = "auto", post: tuple[str, ...] = ()
) -> PipelineConfig:
    """The accuracy benchmarks' pipeline: pipelines/exact with culled lights, linear output, `samples` per pixel;
    `post`: passes after the composite, as YAML flow items (the frame is then theirs, not linear)."""
    after = "".join(f", {p}" for p in post)
    return pipeline_from_text(
        f"name: linear_aa{samples}{'_post' if post else ''}\n"
        f"transparency: {{method: presort_lf_et, threshold: {threshold}, budget_mb: auto}}\n"
        f"antialiasing: {{samples: {samples}}}\n"
        f"passes: [geometry, {{light_culling: {{mode: {light_culling}}}}}, composite{after}]\n",
        f"<linear pipeline, {samples} samples{', then ' + ', '.join(post) if post else ''}>",
    )


def exact_reference(
    ctx: moderngl.Context,
    scene: Scene,
    width: int,
    height: int,
    k: int,
    tile_px: int = 2048,
    method: str = "presort_lf",
) -> Supersampled:
    """The supersampled reference of `scene` on context `ctx`: `method` (exact; presort_lf has no early
    termination) through the hardware rasterizer, as every sample count's coverage rules, k x the size."""
    r = Renderer(linear_pipeline(1), ctx=ctx, method=method, method_overrides={"raster": "hardware"})
    try:
        return supersampled(r, scene, width, height, k, tile_px)
    finally:
        r.release()


def edge_pixels(reference: Supersampled, tolerance: float = 0.05) -> np.ndarray:
    """(H, W) bool: pixels whose k x k sub-pixels span more than `tolerance` (linear) in a channel.

    Smooth shading varies little inside one pixel; a silhouette, a boundary or an intersection
    crossing the pixel makes its sub-pixels differ: the pixels anti-aliasing is for.
    """
    return reference.spread > tolerance
