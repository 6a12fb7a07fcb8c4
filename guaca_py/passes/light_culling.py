"""Light-culling pass: frustum-culls lights on the CPU and builds the per-tile light bit grid on the GPU."""

from __future__ import annotations

import math
from functools import cached_property

import moderngl
import numpy as np

from ..errors import DeviceError
from ..gpu_counters import UploadBuffer
from ..pipeline.resources import LightGrid
from ..pipeline.settings import Setting, positive
from ..registry import register
from ..shaders import mat_bytes, set_uniform, set_uniforms
from ..shaders.slots import Buffer, Image
from .base import (
    GL_SHADER_IMAGE_ACCESS_BARRIER_BIT,
    GL_TEXTURE_FETCH_BARRIER_BIT,
    GL_TEXTURE_UPDATE_BARRIER_BIT,
    Pass,
)
from .light_grid_cpu import compare_grids, exact_tile_lights, grid_shape, unpack_grid
from .lights import light_table, pack_lights, reaches_everywhere, visible_mask

MODES = ("auto", "conservative", "fallback", "off")
ARC_SEGMENTS = 8  # proxy profile: segments of the range sphere's arc
RING_SEGMENTS = 16  # proxy: sides of the circumscribed polygon around the light's axis
# Largest distance of a proxy vertex from the light, in units of its range.
PROXY_EXTENT = 1.0 / (math.cos(math.pi / RING_SEGMENTS) * math.cos(math.pi / (2 * ARC_SEGMENTS)))
PROXY_VERTICES = (ARC_SEGMENTS + 2) * RING_SEGMENTS * 6
_PLANE_MARGIN = 1e-3  # relative: proxies this close to the near/far plane count as crossing it
# up to this many lights the light table is kept while their values stay the same; comparing every
# field costs more than gathering the table past ~5 lights (2 lights: 7.6 against 16.8 us, 16: 58 against
# 29 us, timeit on the development machine)
_KEYED_LIGHTS = 4


def _tile_size(v) -> str | None:
    return None if 1 <= v <= 256 else f"must be in 1..256 pixels, got {v}"


# The grid is next written by the proxies' image atomics, then read by texelFetch (composite, debug
# view) or read back (grid_bits): not as a buffer of any kind.
_GRID_BARRIERS = GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT
CACHE_TILE_BITS_ABOVE = 64  # layers (2048 lights): 'auto' caches a tile's bits per pixel beyond this


@register("pass")
class LightCullingPass(Pass):
    """Assigns the visible lights to screen tiles (bit i of a tile set where light i may touch it).

    Modes: 'conservative' rasterizes each light's proxy at tile resolution with NV conservative
    rasterization; 'fallback' emulates it (bounding box + exact triangle/tile overlap test per
    fragment); 'auto' picks conservative where the device has it; 'off' builds no grid and
    shades every light everywhere (the comparison baseline).
    """

    name = "light_culling"
    reads = ("lights",)
    writes = ("light_grid",)
    SETTINGS = {
        "mode": Setting((str,), "auto", "light grid construction", choices=MODES),
        "tile_size": Setting((int,), 16, "tile edge in pixels", check=_tile_size),
        "max_lights": Setting((int,), 1024, "most visible lights a frame may use", check=positive),
        "tile_bits": Setting(
            (str,),
            "auto",
            "how composite reads a tile's light bits: 'cache' (once per pixel "
            "into a local array), 'fetch' (per shaded fragment, from the texture cache) or "
            "'auto'",
            choices=("auto", "cache", "fetch"),
        ),
        "report_accuracy": Setting(
            (bool,), False, "compare the grid with the exact CPU answer every frame (slow; stats)"
        ),
    }

    def __init__(self, device, settings, readers=None):
        super().__init__(device, settings, readers)
        self._lights = UploadBuffer(self.ctx)  # shaders read it per fragment: GPU-placed, filled by copy
        self._everywhere = self._grid = self._fbo = None
        self._grid_key = None
        self.layers_allocated = 1
        self.packed_lights: list = []  # lights in bit order of the last frame
        self.grid_skipped: str | None = None  # why the last frame built no grid (mode 'off' aside)
        self.grids_built = 0  # grids built (clear and proxy dispatches) since the renderer was made
        self._raw_gl = None
        self._vaos: dict = {}
        self._table, self._table_key = None, None  # the last light table and the light values it holds
        self.mode, self.mode_note = self._resolve_mode(settings["mode"], device.caps)

    def _resolve_mode(self, mode: str, caps) -> tuple[str, str]:
        """The construction mode this device runs, and why."""
        if mode in ("off", "fallback"):
            return mode, "as configured"
        from ..gl_state import GL_CONSERVATIVE_RASTERIZATION_NV, raw_gl

        if not caps.conservative_raster:
            if mode == "conservative":
                raise DeviceError(
                    f"light_culling mode 'conservative' needs GL_NV_conservative_raster, which "
                    f"{caps.gl_renderer} does not have; use mode 'auto' or 'fallback'"
                )
            return "fallback", "GL_NV_conservative_raster not available"
        gl = raw_gl()
        if gl is None or not gl.try_enable(GL_CONSERVATIVE_RASTERIZATION_NV):
            reason = (
                "no GL library to call glEnable through"
                if gl is None
                else "glEnable(GL_CONSERVATIVE_RASTERIZATION_NV) did not take effect"
            )
            if mode == "conservative":
                raise DeviceError(f"light_culling mode 'conservative': {reason} on {caps.gl_renderer}")
            return "fallback", reason
        gl.disable(GL_CONSERVATIVE_RASTERIZATION_NV)
        self._raw_gl = gl
        return "conservative", f"GL_NV_conservative_raster via {gl.source}"

    # ------------------------------------------------------------------ CPU side
    def _light_table(self, lights) -> np.ndarray:
        """light_table() of the scene's lights, made again only when a light's values changed.

        A few lights are compared by value, every field (some twenty numpy calls a frame saved);
        more are gathered every frame, as comparing them costs more than gathering them.
        """
        if len(lights) > _KEYED_LIGHTS:
            return light_table(lights)
        key = tuple(l.value_key() for l in lights)
        if key != self._table_key:
            self._table, self._table_key = light_table(lights), key
        return self._table

    def _order(
        self, table: np.ndarray, idx: np.ndarray, view: np.ndarray, near: float, far: float
    ) -> tuple[np.ndarray, int]:
        """Light rows `idx` in bit order: rasterized proxies first, then those reaching every tile; and the split.

        Proxies are clipped by the near and far planes, which removes their caps. A ray from the eye
        that meets the clipped volume still crosses a drawn face (where it enters or leaves),
        unless the volume spans both planes along it: only such lights (and directional and ambient ones)
        are given every tile.
        """
        rows = table[idx]
        depth = -(rows[:, 0:3] @ view[2, :3] + view[2, 3])
        reach = rows[:, 3] * PROXY_EXTENT * (1.0 + _PLANE_MARGIN)
        spans = (depth - reach <= near * (1.0 + _PLANE_MARGIN)) & (depth + reach >= far * (1.0 - _PLANE_MARGIN))
        everywhere = spans | reaches_everywhere(rows)
        return np.concatenate([idx[~everywhere], idx[everywhere]]), int(np.count_nonzero(~everywhere))

    # ------------------------------------------------------------------ GPU side
    def _ensure_grid(self, tw: int, th: int, layers: int) -> None:
        """Grid texture (tw, th, allocated layers); layers grow by doubling, only when needed."""
        cap = max(1, -(-self.settings["max_lights"] // 32))
        alloc = self.layers_allocated if self._grid is not None and self._grid_key == (tw, th) else 1
        while alloc < layers:
            alloc *= 2
        alloc = max(1, min(alloc, cap))
        if self._grid is not None and self._grid_key == (tw, th) and alloc == self.layers_allocated:
            return
        self._release_grid()
        self._grid = self.ctx.texture_array((tw, th, alloc), 1, dtype="u4")
        self._grid.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._fbo = self.ctx.empty_framebuffer((tw, th))
        self._everywhere = UploadBuffer(self.ctx)
        self._grid_key, self.layers_allocated = (tw, th), alloc

    def _grid_matrix(self, frame, tw: int, th: int) -> np.ndarray:
        """World -> clip of the tile grid: the frame's view-projection with NDC rescaled to whole tiles."""
        t = self.settings["tile_size"]
        sx, sy = frame.width / (t * tw), frame.height / (t * th)
        fix = np.array([[sx, 0, 0, sx - 1], [0, sy, 0, sy - 1], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=np.float64)
        return fix @ frame.projection @ frame.view

    def _build_grid(self, frame, count: int, n_raster: int) -> None:
        from ..gl_state import GL_CONSERVATIVE_RASTERIZATION_NV

        mgl = moderngl
        tw, th = grid_shape(frame.width, frame.height, self.settings["tile_size"])
        layers = -(-count // 32)
        self._ensure_grid(tw, th, layers)
        masks = np.zeros(self.layers_allocated, dtype=np.uint32)
        for i in range(n_raster, count):  # lights that reach every tile
            masks[i // 32] |= np.uint32(1 << (i % 32))
        self._everywhere.upload(masks.tobytes(), min_size=masks.nbytes)
        clear = self.device.programs.compute("light_grid/clear.comp.j2")
        self._grid.bind_to_image(Image.LIGHT_GRID, read=False, write=True)
        self._everywhere.bind(Buffer.LIGHT_GRID_EVERYWHERE)
        set_uniform(clear, "gua_grid_dims", (tw, th, self.layers_allocated))
        clear.run(-(-tw // 8), -(-th // 8), self.layers_allocated)
        self.ctx.memory_barrier(_GRID_BARRIERS)
        self.grids_built += 1
        if n_raster:
            prog = self._proxy_program()
            set_uniforms(
                prog,
                (
                    ("gua_grid_view_projection", mat_bytes(self._grid_matrix(frame, tw, th))),
                    ("gua_first_light", 0),
                    ("gua_grid_size", (float(tw), float(th))),
                ),
            )
            self._fbo.use()
            self.ctx.disable(mgl.DEPTH_TEST | mgl.BLEND | mgl.CULL_FACE)
            self._grid.bind_to_image(Image.LIGHT_GRID, read=True, write=True)
            self._lights.bind(Buffer.LIGHTS)
            vao = self._vaos.get(prog.glo)
            if vao is None:
                vao = self._vaos[prog.glo] = self.ctx.vertex_array(prog, [])
            conservative = self.mode == "conservative"
            if conservative:
                self._raw_gl.enable(GL_CONSERVATIVE_RASTERIZATION_NV)
            try:
                vao.render(mgl.TRIANGLES, vertices=PROXY_VERTICES, instances=n_raster)
            finally:
                if conservative:
                    self._raw_gl.disable(GL_CONSERVATIVE_RASTERIZATION_NV)
            self.ctx.memory_barrier(_GRID_BARRIERS)

    def _proxy_program(self):
        dilate = self.mode == "fallback"
        geo = {"arc_segments": ARC_SEGMENTS, "ring_segments": RING_SEGMENTS}
        stages = {
            "vertex_shader": ("light_grid/proxy.vert.j2", geo),
            "fragment_shader": ("light_grid/mark.frag.j2", {"dilate": dilate}),
        }
        if dilate:
            stages["geometry_shader"] = ("light_grid/dilate.geom.j2", {})
        return self.device.programs.program(stages, label="light grid proxies")

    # ------------------------------------------------------------------ pass
    def execute(self, frame) -> None:
        """Cull, order and upload the visible lights, then (unless mode 'off') build the light grid."""
        table = self._light_table(frame.scene.lights)
        idx = np.flatnonzero(visible_mask(table, frame.projection @ frame.view))
        visible = len(idx)
        dropped = max(0, visible - self.settings["max_lights"])
        idx = idx[: self.settings["max_lights"]]
        n_raster = 0
        if self.mode != "off":
            cam = frame.scene.camera
            idx, n_raster = self._order(table, idx, frame.view, cam.near, cam.far)
        data = pack_lights(table[idx]).tobytes()
        self._lights.upload(data)
        self.packed_lights = lights = [frame.scene.lights[i] for i in idx]
        grid = None
        self.grid_skipped = self._skip_reason(frame, len(lights)) if self.mode != "off" else None
        if self.mode != "off" and self.grid_skipped is None:
            self._build_grid(frame, len(lights), n_raster)
            grid = self._grid
        tw, th = grid_shape(frame.width, frame.height, self.settings["tile_size"])
        frame.resources["light_grid"] = LightGrid(
            buffer=self._lights.buffer,
            count=len(lights),
            grid=grid,
            # no grid built: no layer to read (the composite then reads no grid texel, stale or not)
            layers=-(-len(lights) // 32) if grid is not None else 0,
            layers_allocated=self.layers_allocated,
            tile_size=self.settings["tile_size"],
            tiles=(tw, th),
            template_vars=self.template_vars(),
        )
        stats = {
            "scene": len(frame.scene.lights),
            "visible": visible,
            "shaded": len(lights),
            "dropped_over_max": dropped,
            "mode": self.mode,
            "mode_requested": self.settings["mode"],
            "mode_reason": self.mode_note,
            "tile_size": self.settings["tile_size"],
        }
        frame.stats.memory("lights", len(data))
        if self.grid_skipped is not None:
            stats["grid_skipped"] = self.grid_skipped
        if grid is not None:
            stats.update(
                {
                    "grid": [tw, th],
                    "layers": -(-len(lights) // 32),
                    "layers_allocated": self.layers_allocated,
                    "rasterized": n_raster,
                    "every_tile": len(lights) - n_raster,
                }
            )
            frame.stats.memory("light_grid", tw * th * self.layers_allocated * 4)
            if self.settings["report_accuracy"]:
                stats["grid_check"] = self.grid_check(frame)
        frame.stats["lights"] = stats
        if dropped:
            frame.stats.warn(f"{dropped} visible lights over max_lights={self.settings['max_lights']} were not shaded")

    @cached_property
    def _only_composite_reads_grid(self) -> bool:
        """Whether the composite is the only pass reading the light grid (debug views read it too)."""
        return all(name == "composite" for name in self.readers.get("light_grid", ()))

    def _skip_reason(self, frame, count: int) -> str | None:
        """Why this frame needs no light grid, or None: no light to assign, or no surface to shade.

        Nothing is dispatched then (no grid clear, no proxies); the resource says there is no
        grid, so nothing reads the grid texture's stale bits.
        """
        if self.settings["report_accuracy"]:
            return None  # the grid itself is asked for
        if count == 0:
            return "no visible lights"
        if not frame.draws and self._only_composite_reads_grid:
            return "nothing to shade (no draws)"
        return None

    # ------------------------------------------------------------------ inspection
    def grid_bits(self) -> np.ndarray:
        """Bool (lights, tiles down, tiles across) read back from the last grid; bit order = packed_lights."""
        if self.mode != "off" and self.grid_skipped is not None and not self.packed_lights:
            tw, th = self._grid_key or (0, 0)
            return np.zeros((0, th, tw), dtype=bool)  # no lights: no bits
        if self._grid is None or self.mode == "off" or self.grid_skipped is not None:
            raise RuntimeError(
                f"no light grid: mode 'off', nothing rendered yet or the last frame built none ({self.grid_skipped})"
            )
        tw, th = self._grid_key
        words = np.frombuffer(self._grid.read(), dtype=np.uint32).reshape(self.layers_allocated, th, tw)
        return unpack_grid(words, len(self.packed_lights))

    def grid_check(self, frame) -> dict:
        """Missing and extra (light, tile) pairs of the last grid against the exact float64 CPU answer."""
        exact = exact_tile_lights(
            self.packed_lights, frame.view, frame.projection, frame.width, frame.height, self.settings["tile_size"]
        )
        return compare_grids(exact, self.grid_bits())

    def template_vars(self) -> dict:
        """Shader variables describing how lights are looked up."""
        if self.mode == "off":
            return {"light_grid": False, "max_light_layers": 1}
        how = self.settings["tile_bits"]
        if how == "auto":
            # Measured on the H100 (1024², docs/decisions.md, 2026-11-23 "light grid bits"): a per-pixel array of
            # 32 layers cost 13.5 ms of composite against 7.3 ms fetching per fragment; past 64 layers
            # the per-fragment fetches of empty layers dominate (4096 lights: 54.3 vs 32.7 ms).
            how = "cache" if self.layers_allocated > CACHE_TILE_BITS_ABOVE else "fetch"
        return {"light_grid": True, "max_light_layers": self.layers_allocated, "tile_bits_cached": how == "cache"}

    def _release_grid(self) -> None:
        for o in (self._grid, self._fbo, self._everywhere):
            if o is not None:
                o.release()
        self._grid = self._fbo = self._everywhere = None
        self._grid_key = None

    def release(self) -> None:
        """Free the light buffer and the grid."""
        self._release_grid()
        for vao in self._vaos.values():
            vao.release()
        self._vaos = {}
        self._lights.release()


__all__ = ["LightCullingPass", "MODES", "PROXY_EXTENT"]
