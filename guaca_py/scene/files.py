"""Any scene input as a Scene: scene YAML, a glTF file, or a single mesh file.

A glTF or mesh file given where a scene is expected gets a camera framing it (the glTF's own
camera when it has one) and one default light, so `guaca render model.glb` just works.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .gltf import GLTF_SUFFIXES, load_gltf, scene_bounds
from .graph import Camera, Light, MaterialInstance, Node, Scene
from .loader import load_scene
from .mesh_io import load_mesh_file

#: suffixes read as a single mesh (anything else that is not glTF is read as scene YAML)
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".dae", ".3mf")
#: where the default camera looks from, relative to the model's centre (above, right, in front)
_VIEW_DIRECTION = np.array([0.45, 0.35, 1.0]) / np.linalg.norm([0.45, 0.35, 1.0])


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


def default_light(camera: Camera) -> Light:
    """A white directional key light from above and behind the camera's left shoulder."""
    view = np.subtract(camera.target, camera.position)
    view = view / np.linalg.norm(view)
    direction = view + np.array([0.35, -0.9, 0.0])
    return Light(type="directional", direction=tuple((direction / np.linalg.norm(direction)).tolist()), intensity=3.0)


def scene_from_nodes(nodes: list[Node], camera: Camera | None, source: Path | None) -> Scene:
    """Nodes with a camera (framing them when None) and the default light."""
    cam = camera or framing_camera(*scene_bounds(nodes))
    return Scene(camera=cam, lights=[default_light(cam)], nodes=nodes, source=source)


def load_any(path: str | Path) -> Scene:
    """Scene YAML, a .glb/.gltf file, or a mesh file (OBJ, PLY, STL...) as a renderable Scene."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in GLTF_SUFFIXES:
        content = load_gltf(p)
        return scene_from_nodes(content.nodes, content.camera, p.resolve())
    if suffix in MESH_SUFFIXES:
        mesh = load_mesh_file(p)
        node = Node(name=p.stem, mesh=mesh, material=MaterialInstance("pbr", {}))
        return scene_from_nodes([node], None, p.resolve())
    return load_scene(p)
