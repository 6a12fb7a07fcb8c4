"""glTF 2.0 (.glb / .gltf) files as scene nodes: node hierarchy, meshes, PBR materials, camera.

trimesh parses the file; this module keeps its node graph (local matrices, parent/child
order) instead of flattening it, and maps each glTF material onto the built-in
`gltf_opaque` / `gltf_mask` / `gltf_blend` materials (materials/gltf_*.json):

======================================  =====================================================
glTF                                    guaca_py
======================================  =====================================================
baseColorFactor, baseColorTexture       base_color (vec4), base_color_map (sRGB decoded)
alphaMode OPAQUE / MASK / BLEND         gltf_opaque / gltf_mask (alpha_cutoff) / gltf_blend
metallicFactor, roughnessFactor, map    metallic, roughness, metallic_roughness_map (B, G)
normalTexture (+ scale)                 normal_map, has_normal_map, normal_scale
emissiveFactor, emissiveTexture         emissive, emissive_map (sRGB decoded)
doubleSided                             double_sided (back faces discarded when 0)
======================================  =====================================================

BLEND materials whose alpha is 1 everywhere (factor 1, no texture alpha below 1) become
gltf_opaque: they can never be transparent, so they skip the A-buffer. Occlusion maps,
vertex colours, texture transforms, skins and animations are ignored. trimesh stores
factors as 8-bit values; the file's own floats are used where the material has a unique name.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .graph import Camera, MaterialInstance, MeshData, Node, Transform
from .mesh_io import MESH_FORMATS_HINT, file_error, trimesh_to_meshdata
from .texture import TextureImage

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


def _texture(img, name: str) -> TextureImage | None:
    if img is None:
        return None
    return TextureImage(np.asarray(img.convert("RGBA")), name)


def _float(value, default: float) -> float:
    return default if value is None else float(value)


def gltf_material(mat, exact: dict[str, dict], label: str) -> MaterialInstance:
    """A trimesh PBRMaterial (or None) as a MaterialInstance of the built-in gltf_* materials."""
    from trimesh.visual.material import PBRMaterial

    if mat is not None and not isinstance(mat, PBRMaterial):
        mat = mat.to_pbr()  # e.g. OBJ-style SimpleMaterial
    if mat is None:
        return MaterialInstance("gltf_opaque", {"double_sided": 1})
    file_values = exact.get(mat.name or "", {})
    base = file_values.get("base_color")
    if base is None:
        factor = mat.baseColorFactor
        base = [1.0, 1.0, 1.0, 1.0] if factor is None else (np.asarray(factor, dtype=np.float64) / 255.0).tolist()
    base = [float(v) for v in base] + [1.0] * (4 - len(base))
    emissive = file_values.get("emissive")
    if emissive is None:
        emissive = [0.0, 0.0, 0.0] if mat.emissiveFactor is None else np.asarray(mat.emissiveFactor).tolist()
    u: dict = {
        "base_color": base[:4],
        "metallic": _float(file_values.get("metallic", mat.metallicFactor), 1.0),
        "roughness": _float(file_values.get("roughness", mat.roughnessFactor), 1.0),
        "emissive": [float(v) for v in emissive][:3],
        "double_sided": 1 if mat.doubleSided else 0,
    }
    color_map = _texture(mat.baseColorTexture, f"{label} baseColor")
    for key, img, tag in (
        ("base_color_map", color_map, None),
        ("metallic_roughness_map", mat.metallicRoughnessTexture, "metallicRoughness"),
        ("emissive_map", mat.emissiveTexture, "emissive"),
        ("normal_map", mat.normalTexture, "normal"),
    ):
        tex = img if tag is None else _texture(img, f"{label} {tag}")
        if tex is not None:
            u[key] = tex
    if "normal_map" in u:
        u["has_normal_map"] = 1
    mode = (mat.alphaMode or "OPAQUE").upper()
    if mode == "MASK":
        u["alpha_cutoff"] = _float(mat.alphaCutoff, 0.5)
        return MaterialInstance("gltf_mask", u)
    if mode == "BLEND":
        texture_opaque = color_map is None or bool((color_map.pixels[:, :, 3] == 255).all())
        if base[3] < 1.0 or not texture_opaque:
            return MaterialInstance("gltf_blend", u)
    return MaterialInstance("gltf_opaque", u)


def _camera(scene, bounds_far: float) -> Camera | None:
    """The file's camera as a look-at Camera (glTF cameras look down their local -Z)."""
    if not getattr(scene, "has_camera", False):
        return None
    m = np.asarray(scene.camera_transform, dtype=np.float64)
    pos = m[:3, 3]
    forward = -m[:3, 2] / np.linalg.norm(m[:3, 2])
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    cam = scene.camera
    near = float(getattr(cam, "z_near", 0.01) or 0.01)
    far = float(getattr(cam, "z_far", 0.0) or 0.0)
    return Camera(
        position=tuple(pos.tolist()),
        target=tuple((pos + forward).tolist()),
        up=tuple(up.tolist()),
        fov_y=float(cam.fov[1]),
        near=near,
        far=far if far > near else max(bounds_far, near * 10.0),
    )


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
        scene = trimesh.load(str(p), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable input; all mean "bad file"
        raise fail(f"cannot read glTF file {p}: {exc}", MESH_FORMATS_HINT) from exc
    exact = _exact_factors(_file_json(p))
    graph = scene.graph
    children: dict[str, list[str]] = {}
    edge: dict[str, dict] = {}
    for parent, child, data in graph.to_edgelist():
        children.setdefault(parent, []).append(child)
        edge[child] = data
    meshes: dict[str, MeshData] = {}
    materials: dict[str, MaterialInstance] = {}
    camera_node = getattr(scene.camera, "name", None) if getattr(scene, "has_camera", False) else None

    def build(name: str) -> Node | None:
        data = edge.get(name, {})
        node = Node(name=name, transform=Transform(matrix=data.get("matrix", np.eye(4))))
        geom_name = data.get("geometry")
        geom = scene.geometry.get(geom_name) if geom_name is not None else None
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            if geom_name not in meshes:
                meshes[geom_name] = trimesh_to_meshdata(geom, geom_name, fail, f"{p} mesh '{geom_name}'")
                mat = getattr(geom.visual, "material", None)
                materials[geom_name] = gltf_material(mat, exact, f"{p.name} '{geom_name}'")
            node.mesh = meshes[geom_name]
            node.material = materials[geom_name]
        node.children = [c for c in (build(k) for k in children.get(name, [])) if c is not None]
        if node.mesh is None and not node.children:
            return None  # cameras, lights, empty groups: nothing to draw
        return node

    roots = [n for n in (build(k) for k in children.get(graph.base_frame, []) if k != camera_node) if n is not None]
    if not roots:
        raise fail(f"{p} contains no triangle meshes", "export the model with triangle geometry")
    content = GltfContent(roots, meshes=meshes)
    lo, hi = scene_bounds(roots)
    content.camera = _camera(scene, float(np.linalg.norm(hi - lo)) * 4.0 + 10.0)
    return content


def scene_bounds(nodes: list[Node]) -> tuple[np.ndarray, np.ndarray]:
    """World-space axis-aligned bounds of every mesh under `nodes`."""
    corners = []
    for root in nodes:
        for node, world in root.walk():
            if node.mesh is None:
                continue
            lo, hi = node.mesh.bounds()
            box = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            corners.append((box @ world.T)[:, :3])
    if not corners:
        return np.zeros(3), np.zeros(3)
    pts = np.vstack(corners)
    return pts.min(axis=0), pts.max(axis=0)
