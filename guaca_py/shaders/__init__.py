"""GLSL generation from Jinja2 templates and compilation with readable errors."""

from .templates import ShaderLibrary, SourceMap

__all__ = ["ShaderLibrary", "SourceMap"]
