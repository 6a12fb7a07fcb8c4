"""GLSL generation from Jinja2 templates and compilation with readable errors."""

from .templates import ShaderLibrary, SourceMap, set_uniform, set_uniforms, uniform_names
from .values import mat_bytes

__all__ = ["ShaderLibrary", "SourceMap", "mat_bytes", "set_uniform", "set_uniforms", "uniform_names"]
