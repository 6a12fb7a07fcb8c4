"""What the batch tests share: a small scene file, the turntable job beside it, the sequential loop a batch must equal."""

from __future__ import annotations

import math
from pathlib import Path

SCENE = """\
camera: {position: [0, 0.5, 5], target: [0, 0, 0], up: [0, 1, 0], fov_y: 50, near: 0.1, far: 100}
background: [0.1, 0.1, 0.1]
lights: [{type: point, position: [2, 3, 2], color: [1, 1, 1], intensity: 20, radius: 10}]
nodes:
  - name: back
    mesh: {primitive: quad, size: [4, 4]}
    transform: {translation: [0, 0, -1]}
    material: {description: pbr, uniforms: {albedo: [0.2, 0.8, 0.2]}}
  - name: pane
    mesh: {primitive: quad, size: [2, 2]}
    transform: {rotation_deg: [0, 30, 0]}
    material: {description: unlit, uniforms: {color: [1, 0, 0], alpha: 0.5}}
  - name: box
    mesh: {primitive: box, size: [1, 1, 1]}
    transform: {translation: [0.3, 0.2, 0.5], rotation_deg: [0, -30, 0]}
    material: {description: pbr, uniforms: {albedo: [0, 0, 1], alpha: 0.4}}
"""

#: the issue's turntable, small: frame i at θ = 360·i/frames around the origin, radius 5, height 1.5
TURNTABLE = """\
scene: scene.yaml
frames: {frames}
camera:
  orbit: {{target: [0, 0, 0], radius: 5, height: 1.5, degrees: 360}}
resolution: [{w}, {h}]
variants:
{variants}
"""


def write_job(
    folder: Path, frames: int = 12, variants: str = "  - {name: exact, pipeline: exact}", size=(64, 48)
) -> Path:
    """scene.yaml and job.yaml (the turntable) in `folder`; the job's path."""
    (folder / "scene.yaml").write_text(SCENE)
    job = folder / "job.yaml"
    job.write_text(TURNTABLE.format(frames=frames, variants=variants, w=size[0], h=size[1]))
    return job


def orbit_cameras(frames: int) -> list:
    """The turntable's cameras, computed here from the formula of the job format (not by guaca_py.batch)."""
    from guaca_py.scene.graph import Camera

    out = []
    for i in range(frames):
        theta = math.radians(360.0 * i / frames)
        position = (0.0 + 5.0 * math.sin(theta), 0.0 + 1.5, 0.0 + 5.0 * math.cos(theta))
        out.append(
            Camera(position=position, target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y=50.0, near=0.1, far=100.0)
        )
    return out


def sequential_images(scene_path: Path, cameras: list, pipeline: str = "exact", size=(64, 48), **renderer) -> list:
    """The images of a plain loop: one Renderer, `render` per camera."""
    from guaca_py import Renderer
    from guaca_py.scene.loader import load_scene

    scene = load_scene(scene_path)
    r = Renderer(pipeline, **renderer)
    out = []
    try:
        for cam in cameras:
            scene.camera = cam
            out.append(r.render(scene, *size).image)
    finally:
        r.release()
    return out


def png_pixels(path: Path):
    """The pixels of a PNG file, (H, W, 3) uint8."""
    import numpy as np
    from PIL import Image

    with Image.open(path) as img:
        return np.asarray(img.convert("RGB"))


def differing(files: list[Path], images: list, tolerance: int | None = None) -> list[int]:
    """Indices of the files whose pixels differ from the image's by more than `tolerance` (in 1/255).

    Default: 0 on software rasterizers (the same frame is the same bytes), 1 on GPUs, where the
    order in which fragments arrive changes from run to run, and with it which fragments early
    termination drops behind the exact pipeline's 0.999 threshold (0.26/255, so at most one step of
    rounding).
    """
    import numpy as np

    from guaca_py.context import probe_capabilities

    if tolerance is None:
        tolerance = 0 if probe_capabilities().software else 1
    return [
        i
        for i, (f, img) in enumerate(zip(files, images, strict=True))
        if np.abs(png_pixels(f).astype(int) - img.astype(int)).max() > tolerance
    ]
