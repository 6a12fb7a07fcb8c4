"""Debug post passes: light count per tile and transparent depth complexity, as heat maps with a legend."""

from __future__ import annotations

import numpy as np

from ..pipeline.settings import Setting, positive
from ..registry import register
from ..shaders.slots import Buffer
from .base import FullscreenPass

# Evenly spaced anchors of the heat scale, 0 (black) to max (red); the GLSL interpolates them linearly.
HEAT_ANCHORS = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.16, 0.08, 0.55],
        [0.0, 0.42, 0.95],
        [0.0, 0.78, 0.62],
        [0.55, 0.9, 0.1],
        [1.0, 0.78, 0.0],
        [0.95, 0.12, 0.05],
    ],
    dtype=np.float32,
)
# resolve template -> per-pixel lists in abuffer/layout.glsl.j2 that it walks
_LIST_LAYOUTS = {
    "abuffer/resolve_sorted.glsl.j2": 1,
    "abuffer/resolve_post_sort.glsl.j2": 1,
    "abuffer/resolve_post_merge.glsl.j2": 1,
    "abuffer/resolve_two_lists.glsl.j2": 2,
}


def heat_color(value: float, max_value: int) -> np.ndarray:
    """The heat-scale color (float RGB in [0, 1]) the debug views give `value`; mirrors debug_heat.glsl.j2."""
    t = float(np.clip(value / max_value, 0.0, 1.0)) * (len(HEAT_ANCHORS) - 1)
    i = min(int(t), len(HEAT_ANCHORS) - 2)
    return HEAT_ANCHORS[i] * (1.0 - (t - i)) + HEAT_ANCHORS[i + 1] * (t - i)


def legend_rows(height: int) -> int:
    """Rows at the bottom of the image that the legend covers (see debug_heat.glsl.j2)."""
    s = max(1, height // 160)
    return 2 * s + 5 * s + s + 2 * s + 4 * s + 2 * s


def depth_complexity_unsupported(store) -> str | None:
    """Why the depth-complexity view cannot read the transparent store, or None when it can."""
    if store is None or store.resolve_template() in _LIST_LAYOUTS:
        return None
    return (
        f"method '{store.method_id}' keeps no per-pixel A-buffer lists to count (supported: the "
        f"presort_lf family, post_sort, post_merge16)"
    )


class _HeatView(FullscreenPass):
    """Shared part: RGBA8 target, heat-scale uniforms, writes the display image."""

    writes = ("ldr",)
    target_dtype = "f1"
    default_max = 64

    def _set_heat(self, prog) -> None:
        prog["gua_heat"].write(HEAT_ANCHORS.tobytes())
        prog["gua_heat_max"] = int(self.settings["max"])
        prog["gua_show_legend"] = bool(self.settings["legend"])

    def _finish(self, frame, tex, info: dict) -> None:
        frame.resources["ldr"] = tex
        frame.stats.section("debug_views")[self.name] = info


@register("pass")
class DebugLightCountPass(_HeatView):
    """Heat map of the lights assigned to each tile (with culling off: every light, everywhere)."""

    name = "debug_light_count"
    reads = ("light_grid",)
    SETTINGS = {
        "max": Setting((int,), 64, "light count at the top of the color scale", check=positive),
        "legend": Setting((bool,), True, "draw the color bar with tick marks and labels"),
    }

    def program(self, frame):
        """Program variant for grid / no grid."""
        grid = frame.resources["light_grid"].grid is not None
        tvars = {"light_grid": grid, "heat_anchors": len(HEAT_ANCHORS), "supersample": frame.supersample}
        return self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": ("post/debug_light_count.frag.j2", tvars),
            },
            label=self.name,
        )

    def execute(self, frame) -> None:
        """Draw the light-count heat map."""
        prog = self.program(frame)
        frame.set_frame_uniforms(prog)
        self._set_heat(prog)
        frame.bind_lights(prog)
        tex = self.run_fullscreen(frame, prog, {})
        lg = frame.resources["light_grid"]
        info = {"max_shown": int(self.settings["max"])}
        if lg.grid is not None:
            counts = lg.bits().sum(axis=0)
            info.update(
                tile_max=int(counts.max()) if counts.size else 0,
                tile_mean=round(float(counts.mean()), 3) if counts.size else 0.0,
            )
        else:
            info.update(tile_max=lg.count, tile_mean=float(lg.count))
        self._finish(frame, tex, info)


@register("pass")
class DebugDepthComplexityPass(_HeatView):
    """Heat map of the transparent fragments stored per pixel (A-buffer list lengths)."""

    name = "debug_depth_complexity"
    reads = ("transparent",)
    SETTINGS = {
        "max": Setting((int,), 32, "fragment count at the top of the color scale", check=positive),
        "legend": Setting((bool,), True, "draw the color bar with tick marks and labels"),
    }

    def program(self, frame):
        """Program variant for the frame's transparency method (its list layout and extensions)."""
        store = frame.resources["transparent"]
        tvars = {
            "heat_anchors": len(HEAT_ANCHORS),
            "has_transparency": store is not None,
            "method_extensions": "",
            "walk_limit": 1 << 16,
            "count_lists": 1,
            "supersample": frame.supersample,
        }
        if store is not None:
            tvars.update(store.template_vars())
            tvars.update(method_extensions=store.extensions(), count_lists=_LIST_LAYOUTS[store.resolve_template()])
        return self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": ("post/debug_depth_complexity.frag.j2", tvars),
            },
            label=self.name,
        )

    def __init__(self, device, settings, readers=None):
        super().__init__(device, settings, readers)
        self._count_max = None  # one uint: the frame's largest per-pixel count (a scale for the next frame)

    def execute(self, frame) -> None:
        """Draw the depth-complexity heat map, or report why the method's storage cannot be read."""
        store = frame.resources["transparent"]
        reason = depth_complexity_unsupported(store)
        if reason:
            frame.stats.warn(f"debug_depth_complexity unsupported: {reason}")
            frame.stats.section("debug_views")[self.name] = {"supported": False, "reason": reason}
            return
        prog = self.program(frame)
        frame.set_frame_uniforms(prog)
        self._set_heat(prog)
        if store is not None:
            store.bind(frame, prog)
        self.target(frame)  # a resize reallocates (release()) before the count buffer is bound
        if self._count_max is None:
            self._count_max = self.ctx.buffer(reserve=4)
        self._count_max.clear()
        self._count_max.bind_to_storage_buffer(Buffer.DEBUG_COUNT_MAX)
        tex = self.run_fullscreen(frame, prog, {})
        self._finish(
            frame,
            tex,
            {
                "supported": True,
                "max_shown": int(self.settings["max"]),
                "stored": int(frame.stats.get("fragments", {}).get("stored", 0)),
            },
        )

    def collect(self, frame) -> None:
        """The frame's largest per-pixel count into the stats (`pixel_max`): what a scale fitted to the frame tops at."""
        info = frame.stats.get("debug_views", {}).get(self.name, {})
        if info.get("supported"):
            self.ctx.memory_barrier()  # the fragment shader's atomics before the read
            info["pixel_max"] = int(np.frombuffer(self._count_max.read(), np.uint32)[0])

    def release(self) -> None:
        """Free the target and the count buffer."""
        super().release()
        if self._count_max is not None:
            self._count_max.release()
            self._count_max = None


__all__ = [
    "DebugLightCountPass",
    "DebugDepthComplexityPass",
    "HEAT_ANCHORS",
    "heat_color",
    "legend_rows",
    "depth_complexity_unsupported",
]
