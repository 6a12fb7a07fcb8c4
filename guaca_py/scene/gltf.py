"""glTF 2.0 (.glb / .gltf) files as scene nodes: node hierarchy, meshes, PBR materials, camera.

trimesh parses the file; scene/trimesh_scene.py keeps its node graph (local matrices,
parent/child order) instead of flattening it and maps each glTF material onto the built-in
`gltf_opaque` / `gltf_mask` / `gltf_blend` materials (its module docstring has the table).
This module adds what trimesh drops: the factors as the file wrote them (trimesh stores 8-bit
values; the file's floats are used where the material has a unique name) and the camera's
world transform (trimesh keeps only the camera node's local matrix, so a camera under a
scaled or moved parent would look from the wrong place).
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pyglm import glm

from .mesh_io import MESH_FORMATS_HINT, file_error
from .nodes import Camera, MeshData, Node, scene_bounds
from .trimesh_scene import camera_from_matrix, far_past, nodes_from_trimesh, warn_scene

GLTF_SUFFIXES = (".glb", ".gltf")


@dataclass
class GltfContent:
    """What a glTF file holds: root nodes (with children), its first camera if any."""

    nodes: list[Node]
    camera: Camera | None = None
    meshes: dict[str, MeshData] = field(default_factory=dict)


def _file_json(path: Path) -> dict:
    """The glTF JSON document of a .gltf or .glb file ({} when it cannot be read)."""
    try:
        data = path.read_bytes()
        if data[:4] == b"glTF":
            length = struct.unpack_from("<I", data, 12)[0]
            return json.loads(data[20 : 20 + length])
        return json.loads(data)
    except (OSError, ValueError, struct.error):
        return {}


def _exact_factors(doc: dict) -> dict[str, dict]:
    """Material name -> its pbr factors as written in the file (only for names used once)."""
    mats = doc.get("materials") or []
    names = [m.get("name") for m in mats]
    out = {}
    for m in mats:
        name = m.get("name")
        if name and names.count(name) == 1:
            pbr = m.get("pbrMetallicRoughness") or {}
            out[name] = {
                "base_color": pbr.get("baseColorFactor"),
                "metallic": pbr.get("metallicFactor"),
                "roughness": pbr.get("roughnessFactor"),
                "emissive": m.get("emissiveFactor"),
            }
    return out


def _node_local(node: dict) -> glm.dmat4:
    """A glTF node's local matrix: `matrix` (column-major), else T * R * S."""
    if "matrix" in node:
        return glm.dmat4(np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T)
    t = glm.dvec3(*node.get("translation", (0.0, 0.0, 0.0)))
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    s = glm.dvec3(*node.get("scale", (1.0, 1.0, 1.0)))
    return glm.translate(t) * glm.mat4_cast(glm.dquat(w, x, y, z)) * glm.scale(s)


def camera_node(doc: dict) -> tuple[dict, np.ndarray] | None:
    """The first camera of the file's scene in document order: (its glTF camera object, its world matrix).

    The world matrix is the product of the local matrices from the scene's root down to the
    camera's node.
    """
    nodes, cameras = doc.get("nodes") or [], doc.get("cameras") or []
    scenes = doc.get("scenes") or []
    index = doc.get("scene", 0)
    try:
        if scenes:
            roots = list(scenes[index].get("nodes", []))
        else:  # no scene: every node that is no other's child is a root
            children = {c for n in nodes for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        stack = [(i, glm.dmat4(1.0)) for i in reversed(roots)]
        seen: set[int] = set()
        while stack:
            i, parent = stack.pop()
            if i in seen or not 0 <= i < len(nodes):
                continue
            seen.add(i)
            node = nodes[i]
            world = parent * _node_local(node)
            cam = node.get("camera")
            if cam is not None and 0 <= cam < len(cameras):
                return cameras[cam], np.array(world)
            stack.extend((c, world) for c in reversed(node.get("children", [])))
    except (TypeError, ValueError, IndexError, KeyError, AttributeError):
        return None  # a malformed node graph: trimesh has already read what it could
    return None


def _file_camera(doc: dict, label: str, lo: np.ndarray, hi: np.ndarray) -> Camera | None:
    """The file's first camera at its world transform, or None (none, orthographic, or degenerate)."""
    found = camera_node(doc)
    if found is None:
        return None
    gcam, world = found
    persp = gcam.get("perspective") if isinstance(gcam, dict) else None
    if gcam.get("type") != "perspective" or not isinstance(persp, dict) or "yfov" not in persp:
        warn_scene(
            f"{label}: its camera is {gcam.get('type', 'incomplete')!r}, only perspective cameras are supported; "
            "a camera framing the model is used"
        )
        return None
    near = float(persp.get("znear") or 0.01)
    far = float(persp.get("zfar") or 0.0)  # absent: an infinite projection; this one ends past the model
    if far <= near:
        far = max(far_past(world[:3, 3], lo, hi), near * 10.0)
    fov_y = min(max(math.degrees(float(persp["yfov"])), 1e-3), 179.0)
    return camera_from_matrix(world, fov_y, near, far)


def load_gltf(
    path: str | Path, file_for_errors: str | Path | None = None, line: int | None = None, key: str | None = None
) -> GltfContent:
    """Read a .glb/.gltf file into root Nodes with the file's hierarchy, materials and camera."""
    import trimesh

    p = Path(path)
    fail = file_error(p, file_for_errors, line, key)
    if not p.is_file():
        raise fail(f"glTF file not found: {p}", "check the path; relative paths resolve against the scene file")
    try:
        # a binary glTF under another name is read by its magic bytes (files.py: model_kind)
        kind = p.suffix.lower().lstrip(".") if p.suffix.lower() in GLTF_SUFFIXES else "glb"
        tscene = trimesh.load(str(p), file_type=kind, force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable input; all mean "bad file"
        raise fail(f"cannot read glTF file {p}: {exc}", MESH_FORMATS_HINT) from exc
    doc = _file_json(p)
    roots = nodes_from_trimesh(tscene, str(p), fail, _exact_factors(doc))
    meshes = {id(n.mesh): n.mesh for root in roots for n, _ in root.walk() if n.mesh is not None}
    content = GltfContent(roots, meshes={m.name: m for m in meshes.values()})
    content.camera = _file_camera(doc, p.name, *scene_bounds(roots))
    return content
