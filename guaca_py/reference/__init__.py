"""Ground truth that frames are checked against, in one place for the tests and the benchmarks.

- `cpu`: an independent float64 CPU renderer of unlit triangle scenes (exact sorted compositing,
  edge pixels excluded), sharing no math with the renderer;
- `supersampled`: the exact method at k x the resolution, box filtered (the reference of an
  anti-aliased frame on real scenes), rendered in tiles;
- `errors`: RMSE, largest error and FLIP of linear frames in 1/255;
- `scenes`: the small unlit scenes the CPU renderer models.
"""

from .cpu import (
    camera_basis,
    camera_rays,
    compare,
    edge_mask,
    projected_edges,
    ray_hits,
    reference_of,
    render_reference,
    scene_triangles,
)
from .errors import flip, frame_errors, rmse_255, rmse_max_255, srgb
from .scenes import interpenetrating_scene, layered_quads_scene, origin_camera, quad_mesh, triangle_mesh, unlit
from .supersampled import Supersampled, TileCamera, edge_pixels, exact_reference, linear_pipeline, supersampled

__all__ = [
    "Supersampled",
    "TileCamera",
    "camera_basis",
    "camera_rays",
    "compare",
    "edge_mask",
    "edge_pixels",
    "exact_reference",
    "flip",
    "frame_errors",
    "interpenetrating_scene",
    "layered_quads_scene",
    "linear_pipeline",
    "origin_camera",
    "projected_edges",
    "quad_mesh",
    "ray_hits",
    "reference_of",
    "render_reference",
    "rmse_255",
    "rmse_max_255",
    "scene_triangles",
    "srgb",
    "supersampled",
    "triangle_mesh",
    "unlit",
]
