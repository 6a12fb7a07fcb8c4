"""Scene graph data model: the Scene (camera, background, lights, node tree) and its parts.

The parts (Transform, MeshData, MaterialInstance, Node, Camera, Light) live in
`guaca_py.scene.nodes` and are re-exported here, where code has always imported them from.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .nodes import (
    LIGHT_TYPES,
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
