"""Render passes by config name."""

from .base import Pass
from .composite import CompositePass
from .debug_views import DebugDepthComplexityPass, DebugLightCountPass
from .fxaa import FxaaPass
from .geometry import GeometryPass
from .light_culling import LightCullingPass
from .tone_mapping import ToneMappingPass

PASS_TYPES: dict[str, type[Pass]] = {
    p.name: p
    for p in (
        GeometryPass,
        LightCullingPass,
        CompositePass,
        ToneMappingPass,
        FxaaPass,
        DebugLightCountPass,
        DebugDepthComplexityPass,
    )
}

__all__ = ["PASS_TYPES", "Pass"]
