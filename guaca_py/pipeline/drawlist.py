"""Scene graph → draw list: mesh, material instance, world transform, transparency class."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials import MaterialDescription, MaterialRegistry
from ..scene.graph import MeshData, Scene


@dataclass
class Draw:
    """One mesh drawn with one material instance."""

    index: int
    name: str
    mesh: MeshData
    material: MaterialDescription
    values: dict
    world: np.ndarray
    transparent: bool


def build_draw_list(scene: Scene, materials: MaterialRegistry) -> list[Draw]:
    """Serialize the scene graph; materials and uniform values are checked here (errors cite the scene)."""
    draws: list[Draw] = []
    for node, world in scene.walk():
        if node.mesh is None:
            continue
        inst = node.material
        desc_name = inst.description if inst else "pbr"
        where = getattr(inst, "source", (scene.source, None)) if inst else (scene.source, None)
        desc = materials.get(desc_name, where)
        values = desc.resolve_values(inst.uniforms if inst else {}, where)
        draws.append(Draw(len(draws), node.name, node.mesh, desc, values, world, desc.is_transparent(values)))
    return draws
