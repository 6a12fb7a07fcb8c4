"""Scene graph, procedural primitives, mesh files and YAML scene loading."""

from .files import as_scene
from .graph import LIGHT_TYPES, Camera, Light, MaterialInstance, MeshData, Node, Scene, Transform
from .loader import demo_scene, load, load_scene, load_scene_text
from .mesh_io import load_mesh_file
from .primitives import PRIMITIVE_KINDS, make_primitive, primitive_params
from .trimesh_scene import SceneWarning
from .views import camera_row, cube_map, stereo_pair

__all__ = [
    "LIGHT_TYPES",
    "PRIMITIVE_KINDS",
    "Camera",
    "Light",
    "MaterialInstance",
    "MeshData",
    "Node",
    "Scene",
    "SceneWarning",
    "Transform",
    "as_scene",
    "camera_row",
    "cube_map",
    "demo_scene",
    "load",
    "load_mesh_file",
    "load_scene",
    "load_scene_text",
    "make_primitive",
    "primitive_params",
    "stereo_pair",
]
