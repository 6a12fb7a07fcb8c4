"""Routes each transparent draw to the hardware or the compute rasterizer (`transparency.raster`)."""

from __future__ import annotations

from ..errors import ConfigError
from ..pipeline.device import Device
from .choice import auto_choice, auto_rule, compute_kernels_draw, large_tile_frame, mean_projected_area
from .compute_raster import ComputeRasterizer
from .hardware import HardwareRasterizer


class RasterRouter:
    """Per frame and draw: which rasterizer makes the transparent fragments, and why (frame.stats['raster'])."""

    def __init__(self, device: Device):
        self.device = device
        self.hardware = HardwareRasterizer(device)
        self._compute: ComputeRasterizer | None = None
        self._stats_of = None  # the frame (and pass) whose stats the draws add to
        self._drew_compute = False  # whether that frame drew through the compute rasterizer

    @property
    def compute(self) -> ComputeRasterizer:
        """The compute rasterizer (buffers are made on first use)."""
        if self._compute is None:
            self._compute = ComputeRasterizer(self.device)
        return self._compute

    @staticmethod
    def setting(method) -> str:
        """The method's `raster` setting: hardware, compute or auto."""
        return method.settings.get("raster", "hardware")

    def choose(self, frame, draw) -> tuple[str, str]:
        """(rasterizer, reason) for one transparent draw; `raster: compute` errors where it cannot run."""
        method = frame.method
        setting = self.setting(method)
        if setting == "hardware":
            return "hardware", "raster: hardware"
        refusal = method.compute_raster_refusal()
        if refusal:  # raster: compute was refused when the method was set
            return "hardware", f"method '{method.id}': {refusal}"
        if not compute_kernels_draw(setting, self.device.caps):  # auto on a software rasterizer
            return auto_choice(True, 0.0)
        problem = self.compute.material_problem(draw)
        if problem:
            if setting == "compute":
                raise ConfigError(problem, draw.material.path, None, "transparency.raster")
            return "hardware", problem
        if setting == "compute":
            return "compute", "raster: compute"
        if method.auto_compute_reason:
            return "compute", method.auto_compute_reason
        area = mean_projected_area(draw.mesh, draw.world, frame.projection @ frame.view, frame.width, frame.height)
        return auto_choice(False, area)

    def draw(self, frame, draws, uniforms: dict, per_program=None) -> None:
        """Draw transparent `draws`: compute ones through the kernels, the rest through the fragment pipeline."""
        setting = self.setting(frame.method)
        if self._stats_of is not frame:  # first draw of this frame's pass (a re-render starts afresh)
            frame.stats["raster"] = {"setting": setting}
            self._stats_of = frame
            self._drew_compute = False
        info = frame.stats["raster"]
        if setting == "auto":
            info["rule"] = auto_rule()
        hardware, compute = [], []
        why = info.setdefault("why", {})
        for d in draws:
            kind, reason = self.choose(frame, d)
            (compute if kind == "compute" else hardware).append(d)
            why[f"{kind}: {reason}"] = why.get(f"{kind}: {reason}", 0) + 1
        info["compute_draws"] = info.get("compute_draws", 0) + len(compute)
        info["hardware_draws"] = info.get("hardware_draws", 0) + len(hardware)
        if compute:
            self.compute.draw(frame, compute, uniforms, per_program)
            self._drew_compute = True
        if hardware:
            self.hardware.draw(frame, hardware, transparent=True, uniforms=uniforms, per_program=per_program)

    def nodes_by_tile(self, frame) -> bool:
        """Whether the compute rasterizer drew part of `frame` in tile order with the large frames' buckets, so
        a screen tile's nodes lie together in the pool (the composite then reads the frame in strips)."""
        drew = self._stats_of is frame and self._drew_compute
        return drew and large_tile_frame(frame.method, frame.pixel_count)

    def finish(self, frame) -> bool:
        """The compute rasterizer's totals and memory; True asks for the frame again (its storage grew)."""
        self._stats_of = None
        return self._compute.finish(frame) if self._compute is not None else False

    def release(self) -> None:
        """Free the compute rasterizer's buffers."""
        if self._compute is not None:
            self._compute.release()
