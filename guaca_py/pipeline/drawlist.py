"""Scene graph → draw list: mesh, material instance, world transform, transparency class."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
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


MAX_WORLD = 1.0e7  # float32 positions step by 1 at 1.7e7; llvmpipe's clipper drops triangles past ~1e8


def check_world_extent(node, world: np.ndarray) -> None:
    """Reject a mesh whose world-space corners leave the range float32 vertices and clipping handle."""
    lo, hi = node.mesh.bounds()
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    reach = float(np.max(np.abs(corners @ world.T)[:, :3]))
    if not np.isfinite(reach) or reach > MAX_WORLD:
        file, line = getattr(node, "source", (None, None))
        raise ConfigError(
            f"node '{node.name}' reaches {reach:.3g} units from the origin, beyond {MAX_WORLD:.0e}: float32 "
            "positions and the rasterizer's clipper cannot hold it (the object would vanish)",
            file,
            line,
            "transform",
            "scale the scene to keep coordinates within 1e7 units",
        )


def build_draw_list(scene: Scene, materials: MaterialRegistry) -> list[Draw]:
    """Serialize the scene graph; materials and uniform values are checked here (errors cite the scene)."""
    draws: list[Draw] = []
    for node, world in scene.walk():
        if node.mesh is None:
            continue
        inst = node.material
        desc_name = inst.description if inst else "pbr"
        where = getattr(inst, "source", (scene.source, None)) if inst else (scene.source, None)
        check_world_extent(node, world)
        desc = materials.get(desc_name, where)
        values = desc.resolve_values(inst.uniforms if inst else {}, where)
        draws.append(Draw(len(draws), node.name, node.mesh, desc, values, world, desc.is_transparent(values)))
    return draws
