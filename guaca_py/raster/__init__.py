"""Rasterization of transparent draws: the hardware pipeline or compute kernels (docs/raster.md).

The router (raster/router.py) is imported from its module: it needs the device
(pipeline/device.py), whose mesh cache imports raster/adjacency.py, so this package's
__init__ re-exporting it would make an import circle.
"""

from .choice import AUTO_MAX_MEAN_AREA_PX, RASTER_SETTING, auto_rule

__all__ = ["AUTO_MAX_MEAN_AREA_PX", "RASTER_SETTING", "auto_rule"]
