"""GLSL generation from Jinja2 templates and compilation with readable errors."""

from .templates import ShaderLibrary, SourceMap, uniform_names

__all__ = ["ShaderLibrary", "SourceMap", "uniform_names"]
