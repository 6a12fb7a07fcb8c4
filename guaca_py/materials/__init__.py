"""Material descriptions (JSON + GLSL methods) and their registry."""

from .description import MaterialDescription, Method, UniformSpec, load_material
from .registry import MaterialRegistry

__all__ = ["MaterialDescription", "Method", "UniformSpec", "load_material", "MaterialRegistry"]
