"""GLSL generation from Jinja2 templates and compilation with readable errors."""

from .templates import ShaderLibrary, SourceMap, set_uniform, uniform_names

__all__ = ["ShaderLibrary", "SourceMap", "set_uniform", "uniform_names"]
