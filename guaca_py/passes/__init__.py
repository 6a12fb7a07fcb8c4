"""Render passes. Each pass class registers itself by its config name with `@register("pass")`
(guaca_py/registry.py); importing this package imports every module that defines one."""

from . import composite, debug_views, fxaa, geometry, light_culling, tone_mapping  # noqa: F401  (they register)
from .base import Pass

__all__ = ["Pass"]
