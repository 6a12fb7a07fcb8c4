"""Scene graph, procedural primitives, mesh files and YAML scene loading."""

from .graph import LIGHT_TYPES, Camera, Light, MaterialInstance, MeshData, Node, Scene, Transform
from .loader import demo_scene, load_scene, load_scene_text
from .mesh_io import load_mesh_file
from .primitives import PRIMITIVE_KINDS, make_primitive, primitive_params

__all__ = [
    "LIGHT_TYPES",
    "PRIMITIVE_KINDS",
    "Camera",
    "Light",
    "MaterialInstance",
    "MeshData",
    "Node",
    "Scene",
    "Transform",
    "demo_scene",
    "load_mesh_file",
    "load_scene",
    "load_scene_text",
    "make_primitive",
    "primitive_params",
]
