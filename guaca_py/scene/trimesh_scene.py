"""trimesh scenes and meshes as scene nodes: node graph, 4x4 transforms, camera and materials.

Every file trimesh reads (glTF, OBJ/MTL, PLY, STL, ...) and every trimesh.Scene a program
builds comes through here, so one mapping decides what each kind of trimesh visual renders as:

=======================================  ==========================================================
trimesh                                  guaca_py
=======================================  ==========================================================
PBRMaterial (glTF)                       gltf_opaque / gltf_mask / gltf_blend (table below)
SimpleMaterial (OBJ/MTL)                 gltf_opaque, or gltf_blend when alpha < 1:
  Kd (diffuse), map_Kd                   base_color rgb, base_color_map (sRGB decoded, times Kd)
  d, Tr (= 1 - d)                        base_color alpha (d wins where both are written)
  Ns, Ke                                 roughness (2 / (Ns + 2)) ** 0.25, emissive
ColorVisuals (face or vertex colours)    pbr: albedo and alpha of the most common colour
no visual                                pbr (its defaults: light grey, roughness 0.5)
=======================================  ==========================================================

glTF materials (PBRMaterial):

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
gltf_opaque: they can never be transparent, so they skip the A-buffer. OBJ materials are drawn
from both sides (OBJ has no notion of sidedness) and are dielectric (metallic 0). Colour
textures are sRGB-encoded in both formats, which the gltf_* materials decode (pbr_textured
does not), hence OBJ materials use them too. Occlusion maps, per-vertex colour variation,
texture transforms, skins and animations are ignored; a mesh with varying colours is drawn
in its most common colour, with a warning.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .mesh_io import trimesh_to_meshdata
from .nodes import Camera, MaterialInstance, MeshData, Node, Transform, scene_bounds
from .texture import TextureImage, rgba_pixels


class SceneWarning(UserWarning):
    """A file or trimesh scene loaded, but not entirely as its author meant (what was changed and why)."""


def warn_scene(message: str) -> None:
    """Issue a SceneWarning attributed to the first caller outside guaca_py (the line that loaded the scene)."""
    package = str(Path(__file__).resolve().parents[1])
    frame, level = sys._getframe(1), 2  # stacklevel 2: the caller of this function
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, SceneWarning, stacklevel=level)


def _texture(img, name: str) -> TextureImage | None:
    if img is None:
        return None
    return TextureImage(rgba_pixels(img), name)


def _float(value, default: float) -> float:
    return default if value is None else float(value)


def _blend_or_opaque(uniforms: dict, alpha: float, color_map: TextureImage | None) -> MaterialInstance:
    """gltf_blend when the alpha (factor or texture) can go below 1, else gltf_opaque."""
    texture_opaque = color_map is None or bool((color_map.pixels[:, :, 3] == 255).all())
    return MaterialInstance("gltf_blend" if alpha < 1.0 or not texture_opaque else "gltf_opaque", uniforms)


def pbr_material(mat, exact: dict[str, dict], label: str) -> MaterialInstance:
    """A trimesh PBRMaterial (glTF) as a MaterialInstance of the built-in gltf_* materials.

    `exact` maps material names to the factors the file wrote (trimesh rounds them to 8 bits).
    """
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
        return _blend_or_opaque(u, base[3], color_map)
    return MaterialInstance("gltf_opaque", u)


def _mtl_number(kwargs: dict, key: str) -> float | None:
    """A one-number MTL statement trimesh kept unparsed (`d 0.5` arrives as ['0.5']), or None."""
    value = kwargs.get(key)
    if isinstance(value, (list, tuple)):
        value = value[0] if value else None
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def mtl_alpha(kwargs: dict) -> float:
    """Opacity of an MTL material: `d` (dissolve), else 1 - `Tr`, else 1; clamped to [0, 1]."""
    d = _mtl_number(kwargs, "d")
    if d is None:
        tr = _mtl_number(kwargs, "tr")
        d = 1.0 if tr is None else 1.0 - tr
    return min(max(d, 0.0), 1.0)


def simple_material(mat, label: str) -> MaterialInstance:
    """A trimesh SimpleMaterial (OBJ/MTL: Kd, map_Kd, d/Tr, Ns, Ke) as a gltf_opaque/gltf_blend instance."""
    kwargs = getattr(mat, "kwargs", None) or {}
    kd = kwargs.get("kd")
    if kd is None or np.size(kd) != 3:
        kd = np.asarray(mat.diffuse if mat.diffuse is not None else [255, 255, 255], dtype=np.float64)[:3] / 255.0
    rgb = [min(max(float(c), 0.0), 1.0) for c in np.ravel(kd)[:3]]
    alpha = mtl_alpha(kwargs)
    ns = mat.glossiness if mat.glossiness is not None else _mtl_number(kwargs, "ns")
    ke = kwargs.get("ke")
    try:
        emissive = [max(float(v), 0.0) for v in ke][:3] if ke is not None and len(ke) == 3 else [0.0, 0.0, 0.0]
    except (TypeError, ValueError):
        emissive = [0.0, 0.0, 0.0]
    u: dict = {
        "base_color": rgb + [alpha],
        "metallic": 0.0,
        "roughness": 1.0 if ns is None else float((2.0 / (max(float(ns), 0.0) + 2.0)) ** 0.25),
        "emissive": emissive,
        "double_sided": 1,
    }
    color_map = _texture(getattr(mat, "image", None), f"{label} map_Kd")
    if color_map is not None:
        u["base_color_map"] = color_map
    return _blend_or_opaque(u, alpha, color_map)


def color_material(visual, label: str) -> MaterialInstance:
    """trimesh ColorVisuals (face or vertex colours, 8-bit linear RGBA) as a pbr instance of their main colour."""
    if not visual.defined:
        return MaterialInstance("pbr", {})
    colors = visual.face_colors if visual.kind == "face" else visual.vertex_colors
    rgba = np.asarray(visual.main_color, dtype=np.float64) / 255.0
    if len(colors) and np.any(colors != colors[0]):
        warn_scene(
            f"{label}: per-{visual.kind} colours vary, drawn in the most common one "
            f"{tuple(int(c) for c in visual.main_color)} (colour attributes are not supported; "
            "bake them into a texture for a textured material)"
        )
    u: dict = {"albedo": [float(c) for c in rgba[:3]]}
    if rgba[3] < 1.0:
        u["alpha"] = float(rgba[3])
    return MaterialInstance("pbr", u)


def material_of(geom, exact: dict[str, dict], label: str) -> MaterialInstance:
    """The material a trimesh.Trimesh renders with, from whatever visual it carries."""
    from trimesh.visual import ColorVisuals
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    visual = getattr(geom, "visual", None)
    if isinstance(visual, ColorVisuals):
        return color_material(visual, label)
    mat = getattr(visual, "material", None)
    if isinstance(mat, PBRMaterial):
        return pbr_material(mat, exact, label)
    if isinstance(mat, SimpleMaterial):
        return simple_material(mat, label)
    if mat is not None and hasattr(mat, "to_pbr"):  # MultiMaterial and the like
        return pbr_material(mat.to_pbr(), exact, label)
    return MaterialInstance("pbr", {})


def nodes_from_trimesh(
    tscene, label: str, fail: Callable[[str, str], ConfigError], exact: dict[str, dict] | None = None
) -> list[Node]:
    """The root Nodes of a trimesh.Scene with its node graph kept: local 4x4 matrices, children, materials.

    Geometry that is not a triangle mesh (points, paths) and the camera node are left out; each
    geometry becomes one MeshData and one MaterialInstance shared by every node that instances it.
    """
    import trimesh

    graph = tscene.graph
    children: dict[str, list[str]] = {}
    edge: dict[str, dict] = {}
    for parent, child, data in graph.to_edgelist():
        children.setdefault(parent, []).append(child)
        edge[child] = data
    meshes: dict[str, MeshData] = {}
    materials: dict[str, MaterialInstance] = {}
    camera_node = getattr(tscene.camera, "name", None) if getattr(tscene, "has_camera", False) else None
    exact = exact or {}

    def build(name: str, depth: int) -> Node | None:
        if depth > 1000:
            raise fail(f"{label}: the node graph is deeper than 1000 levels or has a cycle", "flatten the hierarchy")
        data = edge.get(name, {})
        node = Node(name=str(name), transform=Transform(matrix=data.get("matrix", np.eye(4))))
        geom_name = data.get("geometry")
        geom = tscene.geometry.get(geom_name) if geom_name is not None else None
        if isinstance(geom, trimesh.Trimesh) and len(geom.faces):
            if geom_name not in meshes:
                what = f"{label} mesh '{geom_name}'"
                meshes[geom_name] = trimesh_to_meshdata(geom, str(geom_name), fail, what)
                materials[geom_name] = material_of(geom, exact, what)
            node.mesh = meshes[geom_name]
            node.material = materials[geom_name]
        node.children = [c for c in (build(k, depth + 1) for k in children.get(name, [])) if c is not None]
        if node.mesh is None and not node.children:
            return None  # cameras, lights, empty groups, point clouds: nothing to draw
        return node

    roots = [build(k, 0) for k in children.get(graph.base_frame, []) if k != camera_node]
    roots = [n for n in roots if n is not None]
    if not roots:
        if tscene.geometry:
            raise fail(
                f"{label} holds no triangles (only points, lines or empty meshes)",
                "point clouds and line drawings cannot be rendered; export triangles",
            )
        raise fail(f"{label} contains no geometry", "the file is empty or not in a format trimesh understands")
    return roots


def trimesh_camera(tscene, far_default: float) -> Camera | None:
    """A trimesh scene's camera (its world transform from the graph; looks down its local -Z), or None."""
    if not getattr(tscene, "has_camera", False):
        return None
    cam = tscene.camera
    near = float(getattr(cam, "z_near", 0.01) or 0.01)
    far = float(getattr(cam, "z_far", 0.0) or 0.0)
    return camera_from_matrix(
        np.asarray(tscene.camera_transform, dtype=np.float64),
        float(cam.fov[1]),
        near,
        far if far > near else max(far_default, near * 10.0),
    )


def camera_from_matrix(world: np.ndarray, fov_y: float, near: float, far: float) -> Camera | None:
    """A look-at Camera from a camera node's world matrix (scale and shear removed), or None when degenerate."""
    pos = world[:3, 3]
    back, up = world[:3, 2], world[:3, 1]
    nb, nu = float(np.linalg.norm(back)), float(np.linalg.norm(up))
    if not (nb > 0 and nu > 0 and np.isfinite(world).all()):
        return None
    forward, up = -back / nb, up / nu
    if np.linalg.norm(np.cross(forward, up)) < 1e-9:
        return None
    return Camera(
        position=tuple(pos.tolist()),
        target=tuple((pos + forward).tolist()),
        up=tuple(up.tolist()),
        fov_y=fov_y,
        near=near,
        far=far,
    )


def _in_memory_error(reason: str, hint: str) -> ConfigError:
    return ConfigError(reason, hint=hint)


def trimesh_contents(obj) -> tuple[list[Node], Camera | None]:
    """The root Nodes and the camera (None when it has none) of a trimesh.Scene or trimesh.Trimesh."""
    import trimesh

    if isinstance(obj, trimesh.Trimesh):
        obj = trimesh.Scene(obj)
    if not isinstance(obj, trimesh.Scene):
        raise TypeError(f"Scene.from_trimesh takes a trimesh.Scene or trimesh.Trimesh, got {type(obj).__name__}")
    nodes = nodes_from_trimesh(obj, "trimesh scene", _in_memory_error)
    far = 100.0
    if getattr(obj, "has_camera", False):
        far = far_past(np.asarray(obj.camera_transform, dtype=np.float64)[:3, 3], *scene_bounds(nodes))
    return nodes, trimesh_camera(obj, far)


def far_past(eye: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """A far-plane distance beyond every corner of the box [lo, hi] seen from `eye`."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return float(np.linalg.norm(corners - eye, axis=1).max()) * 1.5 + 1e-3
