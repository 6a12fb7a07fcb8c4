"""GLSL generation from Jinja2 templates and compilation with readable errors."""

from .templates import ShaderLibrary, SourceMap, mat_bytes, program_key, set_uniform, set_uniforms, uniform_names

__all__ = ["ShaderLibrary", "SourceMap", "mat_bytes", "program_key", "set_uniform", "set_uniforms", "uniform_names"]
