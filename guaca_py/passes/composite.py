"""Shade-composite pass: shades and blends transparent and opaque fragments front to back."""

from __future__ import annotations

import numpy as np

from ..pipeline.resources import HOST_MARK
from ..pipeline.retry import settle
from ..raster.compute_raster import ORDER_TILE_BITS
from ..registry import register
from ..shaders import set_uniform
from .base import FullscreenPass


def composite_edge(supersample: int) -> int:
    """Workgroup edge of the composite: 8, or the multiple of `supersample` from 8 up (whole blocks per group)."""
    return supersample * -(-8 // supersample)


# Launch strips two screen tiles wide. H100, presort_lf_et, composite ms (rows / 1 tile / 2 tiles / half a
# tile): hairball_v1 at 4096² 6.49 / 3.40 / 2.65 / 5.87 (52M nodes), the dragons at 4096² 1.135 / 1.15 /
# 1.10 / 1.21, hairball_v1 at 3072² 1.26 / 1.31 / 1.29 / 1.43 (docs/decisions.md, 2026-11-28).
STRIP_TILES = 2


def composite_strip(store, width: int, edge: int) -> int:
    """Workgroups per launch strip of the composite over a frame `width` pixels wide: where the store's nodes
    lie together by screen tile (the compute rasterizer drew in tile order with the large frames' buckets,
    raster/choice.py large_tile_frame), STRIP_TILES screen tiles wide, so the workgroups in flight read a
    few tiles' nodes (a row of the frame crosses every tile, and their nodes together outgrow the GPU's
    cache); 0 (row by row) otherwise."""
    if store is None or not store.nodes_by_tile:
        return 0
    return max(1, -(-(STRIP_TILES * (width >> ORDER_TILE_BITS)) // edge))


@register("pass")
class CompositePass(FullscreenPass):
    """Full-screen pass producing linear HDR color ('hdr').

    Over the host's layer (render(..., over_target=True)) it draws no background: it stores
    premultiplied colour and the frame's coverage as alpha, which the presenter blends over the
    host's colour, and it does not shade the G-buffer pixels that hold the host's surface.

    With a per-pixel epilogue (tone mapping right after it, nothing else reading 'hdr': see
    pipeline/assemble.py) it applies that to each pixel before storing and writes the
    epilogue's output ('ldr', RGBA8) instead.
    """

    name = "composite"
    reads = ("gbuffer", "transparent", "light_grid", "host_layer")
    writes = ("hdr",)
    target_dtype = "f4"
    compute = True
    template = "composite/shade_composite.comp.j2"
    accepts_epilogue = True

    def __init__(self, device, settings, readers=None):
        super().__init__(device, settings, readers)
        # Only tone mapping reads the HDR result when a pipeline has it, and half floats hold more than
        # its 8-bit output resolves (half the bytes to write and read); the linear output stays float32.
        if "tone_mapping" in self.readers.get("hdr", ()):
            self.target_dtype = "f2"

    def set_epilogue(self, epilogue) -> None:
        """Store `epilogue`'s per-pixel result (display-referred 8-bit) instead of the HDR colour."""
        self.release()  # the target changes format
        self.epilogue = epilogue
        self.writes = epilogue.writes
        self.target_dtype = "f1"

    def program(self, frame):
        """Composite program for this method, light lookup and transparency presence."""
        store = frame.resources["transparent"]
        g = frame.resources["gbuffer"]
        tvars = dict(
            has_transparency=store is not None,
            has_opaque=g.has_opaque,
            over_host=frame.resources["host_layer"] is not None,
            host_mark=HOST_MARK,
            **frame.shading_vars(),
            method_extensions=store.resolve_extensions() if store else "",
            method_resolve_template=store.resolve_template() if store else "",
            **(store.template_vars() if store else {}),
        )
        tvars["aa_samples"] = self.device.samples  # per-sample accumulators where > 1
        tvars["supersample"] = frame.supersample  # rendered pixels averaged into each output pixel
        tvars["local_edge"] = composite_edge(frame.supersample)
        tvars["tone_map"] = self.epilogue is not None
        if self.epilogue is not None:
            tvars.update(self.epilogue.epilogue_vars())
        return self.compile(tvars)

    def execute(self, frame) -> None:
        """Shade every pixel; writes frame.resources['hdr']."""
        store = frame.resources["transparent"]
        if store is not None and store.draws_in_composite:  # after light culling: it shades as it draws
            settle(lambda: store.draw(frame), frame.stats)
        prog = self.program(frame)
        frame.set_frame_uniforms(prog)
        frame.bind_lights(prog)
        if store is not None:
            store.bind(frame, prog)
        threshold = store.threshold() if store else 1.0
        set_uniform(prog, "gua_threshold", threshold)  # compiled out when nothing is composited under the fragments
        set_uniform(prog, "gua_background", np.asarray(frame.scene.background, dtype=np.float32).tobytes())
        if self.epilogue is not None:
            self.epilogue.set_epilogue_uniforms(prog)
        g = frame.resources["gbuffer"]
        edge = composite_edge(frame.supersample)
        tex = self.run_fullscreen(
            frame,
            prog,
            {
                "gbuf_albedo": g.albedo,
                "gbuf_normal": g.normal,
                "gbuf_material": g.material,
                "gbuf_depth": g.depth,
            },
            scale=frame.supersample,  # an invocation per rendered pixel
            edge=edge,
            strip=composite_strip(store, frame.width, edge),
        )
        if store is not None:
            store.after_composite(frame)
        if store is None and not g.has_opaque:  # nothing drawn: one colour everywhere (background or none)
            frame.uniform_textures.add(tex.glo)
        frame.resources[self.writes[0]] = tex
