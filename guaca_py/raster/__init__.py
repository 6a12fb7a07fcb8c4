"""Rasterization of transparent draws: the hardware pipeline or compute kernels (docs/raster.md)."""

from .choice import AUTO_MAX_MEAN_AREA_PX, RASTER_SETTING, auto_rule
from .router import RasterRouter

__all__ = ["AUTO_MAX_MEAN_AREA_PX", "RASTER_SETTING", "RasterRouter", "auto_rule"]
