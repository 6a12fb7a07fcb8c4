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
    model_bytes: bytes | None = None  # world and inverse-transpose as GL bytes, when a DrawCache made them
    normal_bytes: bytes | None = None


def build_draw_list(scene: Scene, materials: MaterialRegistry, cache=None) -> list[Draw]:
    """Serialize the scene graph; materials and uniform values are checked here (errors cite the scene).

    With a DrawCache (pipeline/draw_cache.py), matrices and resolved materials of unchanged
    nodes are reused from earlier frames.
    """
    if cache is not None:
        return _build_cached(scene, materials, cache)
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


def _build_cached(scene: Scene, materials: MaterialRegistry, cache) -> list[Draw]:
    from .draw_cache import material_key

    draws: list[Draw] = []

    def resolver(inst):
        def resolve():
            desc_name = inst.description if inst else "pbr"
            where = getattr(inst, "source", (scene.source, None)) if inst else (scene.source, None)
            desc = materials.get(desc_name, where)
            values = desc.resolve_values(inst.uniforms if inst else {}, where)
            return desc, values, desc.is_transparent(values)

        return resolve

    def visit(node, parent_key, parent_world):
        key, world, model_bytes, normal_bytes = cache.world(parent_key, parent_world, node.transform)
        if node.mesh is not None:
            inst = node.material
            desc, values, transparent = cache.material(material_key(inst, scene.source), resolver(inst))
            draws.append(
                Draw(len(draws), node.name, node.mesh, desc, values, world, transparent, model_bytes, normal_bytes)
            )
        for child in node.children:
            visit(child, key, world)

    for root in scene.nodes:
        visit(root, None, None)
    cache.end_frame()
    return draws
