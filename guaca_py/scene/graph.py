"""Scene graph data model: the Scene (camera, background, lights, node tree) and its parts.

The parts (Transform, MeshData, MaterialInstance, Node, Camera, Light) live in
`guaca_py.scene.nodes` and are re-exported here, where code has always imported them from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .nodes import (
    LIGHT_TYPES,
    MAX_RADIANCE,
    MAX_WORLD,
    Camera,
    Light,
    MaterialInstance,
    MeshData,
    Node,
    Transform,
    scene_bounds,
)


@dataclass
class Scene:
    """Everything a frame needs: camera, background, lights and the node tree."""

    camera: Camera = field(default_factory=Camera)
    background: tuple[float, float, float] = (0.1, 0.1, 0.1)
    lights: list[Light] = field(default_factory=list)
    nodes: list[Node] = field(default_factory=list)
    source: Path | None = None

    def __post_init__(self):
        self.check_background()

    def check_background(self) -> None:
        """Refuse a background that is not 3 finite numbers in [-MAX_RADIANCE, MAX_RADIANCE] (ConfigError)."""
        try:
            bg = np.asarray(self.background, dtype=np.float64)
        except (TypeError, ValueError):
            bg = None
        if bg is None or bg.shape != (3,) or not np.all(np.isfinite(bg)) or np.max(np.abs(bg)) > MAX_RADIANCE:
            raise ConfigError(
                f"must be 3 finite numbers of magnitude at most {MAX_RADIANCE:g}, got {self.background!r}",
                key="background",
                hint="linear RGB, e.g. (0.1, 0.1, 0.1)",
            )

    def check(self) -> None:
        """Refuse a camera, lights or background no frame can be drawn with (each names its field)."""
        self.camera.check()
        self.check_background()
        for i, light in enumerate(self.lights):
            light.check(f"lights[{i}]")

    def walk(self):
        """Yield (node, world matrix) for every node in the scene, in document order."""
        for n in self.nodes:
            yield from n.walk()

    @classmethod
    def from_trimesh(cls, scene) -> Scene:
        """A trimesh.Scene (or one trimesh.Trimesh) as a Scene, its node graph kept.

        Nodes keep their parent/child structure and 4x4 local matrices; the scene's camera (with
        its world transform) becomes the camera, else one framing the model; PBR, OBJ/MTL and
        colour materials keep their colours, textures and alpha (scene/trimesh_scene.py has the
        table). Lights: the default rig (a key and a fill directional light and an ambient term).
        """
        from .framing import camera_and_lights
        from .trimesh_scene import trimesh_contents

        nodes, camera = trimesh_contents(scene)
        camera, lights = camera_and_lights(nodes, camera, "trimesh scene")
        return cls(camera=camera, lights=lights, nodes=nodes)


__all__ = [
    "LIGHT_TYPES",
    "MAX_RADIANCE",
    "MAX_WORLD",
    "Camera",
    "Light",
    "MaterialInstance",
    "MeshData",
    "Node",
    "Scene",
    "Transform",
    "scene_bounds",
]
