"""Light-culling pass: enumerates visible lights and uploads them for the composite pass."""
from __future__ import annotations


from ..pipeline.settings import Setting, positive
from .base import Pass
from .lights import pack_lights, visible_lights


class LightCullingPass(Pass):
    """Frustum-culls lights on the CPU and uploads them; mode 'off' shades every light everywhere."""

    name = "light_culling"
    reads = ("lights",)
    writes = ("light_grid",)
    SETTINGS = {
        "mode": Setting((str,), "off", "light grid construction", choices=("off",)),
        "tile_size": Setting((int,), 16, "tile edge in pixels", check=positive),
        "max_lights": Setting((int,), 1024, "most visible lights a frame may use", check=positive),
    }

    def __init__(self, renderer, settings):
        super().__init__(renderer, settings)
        self._buffer = None

    def execute(self, frame) -> None:
        """Upload the visible lights; the grid is None in mode 'off'."""
        lights = visible_lights(frame.scene.lights, frame.projection @ frame.view)
        dropped = max(0, len(lights) - self.settings["max_lights"])
        lights = lights[: self.settings["max_lights"]]
        data = pack_lights(lights).tobytes()
        if self._buffer is None or self._buffer.size < len(data):
            if self._buffer is not None:
                self._buffer.release()
            self._buffer = self.ctx.buffer(reserve=max(len(data), 64))
        self._buffer.write(data)
        frame.resources["light_grid"] = {"buffer": self._buffer, "count": len(lights), "grid": None}
        frame.stats["lights"] = {"scene": len(frame.scene.lights), "visible": len(lights),
                                 "dropped_over_max": dropped, "mode": self.settings["mode"]}
        frame.stats.setdefault("memory", {})["lights"] = len(data)
        if dropped:
            frame.stats.setdefault("warnings", []).append(
                f"{dropped} visible lights over max_lights={self.settings['max_lights']} were not shaded")

    def bind(self, frame, prog) -> None:
        """Bind the light list (and grid, when built) for a shading program."""
        lg = frame.resources["light_grid"]
        lg["buffer"].bind_to_storage_buffer(3)
        if "gua_light_count" in prog:
            prog["gua_light_count"] = lg["count"]

    def template_vars(self) -> dict:
        """Shader variables describing how lights are looked up."""
        return {"light_grid": False, "max_light_layers": 1}

    def release(self) -> None:
        """Free the light buffer."""
        if self._buffer is not None:
            self._buffer.release()
            self._buffer = None


__all__ = ["LightCullingPass"]
