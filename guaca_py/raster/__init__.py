"""Rasterization of transparent draws: the hardware pipeline or compute kernels (docs/raster.md).

The router is imported from its module, raster/router.py.
"""

from .choice import AUTO_MAX_MEAN_AREA_PX, RASTER_SETTING, auto_rule

__all__ = ["AUTO_MAX_MEAN_AREA_PX", "RASTER_SETTING", "auto_rule"]
