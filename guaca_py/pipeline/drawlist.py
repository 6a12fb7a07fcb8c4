"""Scene graph → draw list: mesh, material instance, world transform, transparency class."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..materials import MaterialDescription, MaterialRegistry
from ..scene.graph import MAX_TREE_DEPTH, MAX_WORLD, MeshData, Scene
from ..shaders import mat_bytes, set_uniform, uniform_names
from .draw_cache import material_key


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

    def model_gl(self) -> bytes:
        """The model matrix as GL bytes (the DrawCache's when it made them)."""
        return self.model_bytes or mat_bytes(self.world)

    def normal_gl(self) -> bytes:
        """The normal matrix (the model's inverse transpose) as GL bytes (the DrawCache's when it made them)."""
        return self.normal_bytes or mat_bytes(np.linalg.inv(self.world).T)

    def write_transform(self, prog) -> None:
        """Write the model and normal matrices a program uses."""
        set_uniform(prog, "gua_model_matrix", self.model_gl())
        if "gua_normal_matrix" in uniform_names(prog):  # the inverse only where it is used
            set_uniform(prog, "gua_normal_matrix", self.normal_gl())


def _mesh_reach(mesh) -> float:
    """Largest absolute object-space coordinate, computed once per mesh content (MeshData.derived)."""
    return mesh.derived("reach", _reach)


def _reach(mesh) -> float:
    return float(np.abs(mesh.positions).max()) if len(mesh.positions) else 0.0


def _drawn(node) -> bool:
    """The node has a mesh with triangles: one without draws nothing. The first look at a mesh each frame, so
    a mesh whose arrays were replaced is checked again here, before anything reads them (MeshData.checked)."""
    return node.mesh is not None and node.mesh.checked().triangle_count > 0


def check_world_extents(placed: list[tuple]) -> None:
    """Reject a mesh whose world-space extent leaves the range float32 vertices and clipping handle.

    `placed` holds (node, world matrix) pairs. A bound, not the exact box: per axis |translation|
    plus the row sum of |M| times the mesh's reach, for all draws in one array operation (it runs
    every frame, also on the cached path).
    """
    if not placed:
        return
    worlds = np.array([w for _, w in placed])
    reach = np.array([_mesh_reach(n.mesh) for n, _ in placed])
    bound = (np.abs(worlds[:, :3, 3]) + np.abs(worlds[:, :3, :3]).sum(axis=2) * reach[:, None]).max(axis=1)
    bad = np.flatnonzero(~(bound <= MAX_WORLD))  # NaN fails too
    if len(bad):
        node = placed[int(bad[0])][0]
        file, line = getattr(node, "source", (None, None))
        raise ConfigError(
            f"node '{node.name}' reaches {bound[bad[0]]:.3g} units from the origin, beyond {MAX_WORLD:.0e}: float32 "
            "positions and the rasterizer's clipper cannot hold it (the object would vanish)",
            file,
            line,
            "transform",
            "scale the scene to keep coordinates within 1e7 units",
        )


def _resolve_material(inst, scene: Scene, materials: MaterialRegistry) -> tuple[MaterialDescription, dict, bool]:
    """A node's material instance (None: default pbr) as description, checked values and transparency."""
    desc_name = inst.description if inst else "pbr"
    where = getattr(inst, "source", (scene.source, None)) if inst else (scene.source, None)
    desc = materials.get(desc_name, where)
    values = desc.resolve_values(inst.uniforms if inst else {}, where)
    return desc, values, desc.is_transparent(values)


def build_draw_list(scene: Scene, materials: MaterialRegistry, cache=None) -> list[Draw]:
    """Serialize the scene graph; materials and uniform values are checked here (errors cite the scene).

    With a DrawCache (pipeline/draw_cache.py), matrices and resolved materials of unchanged
    nodes are reused from earlier frames.
    """
    if cache is not None:
        return _build_cached(scene, materials, cache)
    draws: list[Draw] = []
    placed: list[tuple] = []
    for node, world in scene.walk():
        if not _drawn(node):
            continue
        desc, values, transparent = _resolve_material(node.material, scene, materials)
        draws.append(Draw(len(draws), node.name, node.mesh, desc, values, world, transparent))
        placed.append((node, world))
    check_world_extents(placed)
    return draws


def _build_cached(scene: Scene, materials: MaterialRegistry, cache) -> list[Draw]:
    draws: list[Draw] = []

    def resolver(inst):
        return lambda: _resolve_material(inst, scene, materials)

    def visit(node, parent_key, parent_world, depth=1):
        if depth > MAX_TREE_DEPTH:  # a cycle, or a tree too deep to recurse through: named by the tree's check
            scene.check_structure()
            raise ConfigError(f"nodes nested deeper than {MAX_TREE_DEPTH} levels", key="nodes")
        try:
            key, world_glm, world, model_bytes, normal_bytes = cache.world(parent_key, parent_world, node.transform)
        except ConfigError as exc:  # a transform value changed since construction: named with its node
            file, line = getattr(node, "source", (None, None))
            key = exc.key.replace("Transform", f"{node.name}.transform") if exc.key else None
            raise ConfigError(exc.reason, file, line, key, exc.hint) from None
        if _drawn(node):
            placed.append((node, world))
            inst = node.material
            desc, values, transparent = cache.material(material_key(inst, scene.source), resolver(inst))
            draws.append(
                Draw(len(draws), node.name, node.mesh, desc, values, world, transparent, model_bytes, normal_bytes)
            )
        for child in node.children:
            visit(child, key, world_glm, depth + 1)

    placed: list[tuple] = []
    for root in scene.nodes:
        visit(root, None, None)
    check_world_extents(placed)
    cache.end_frame()
    return draws
