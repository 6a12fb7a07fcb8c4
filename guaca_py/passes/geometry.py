"""Geometry pass: opaque fragments to the G-buffer, transparent ones to the method's storage."""

from __future__ import annotations

import moderngl

from ..pipeline.resources import HOST_MARK, GBuffer, TransparentStore
from ..registry import register
from ..shaders.slots import Texture
from .base import Pass


@register("pass")
class GeometryPass(Pass):
    """Rasterizes the draw list; opaque draws first so hidden transparent fragments are culled early."""

    name = "geometry"
    reads = ("draw_list", "host_layer")
    writes = ("gbuffer", "transparent")

    def __init__(self, device, settings, readers=None):
        super().__init__(device, settings, readers)
        self._gbuffer = None
        self._samples = 1
        self._depth_clean = False  # the G-buffer depth holds 1.0 everywhere (cleared, nothing drawn since)

    def gbuffer(self, frame):
        """G-buffer framebuffer (albedo, normal+roughness, emissive+metalness, depth)."""
        size = (frame.width, frame.height)
        samples = self.device.samples
        if self._gbuffer is None or self._gbuffer.size != size or self._samples != samples:
            self.release()
            ctx = self.ctx
            self._samples = samples
            ms = samples if samples > 1 else 0  # antialiasing: a multisampled G-buffer
            colors = [ctx.texture(size, 4, dtype="f2", samples=ms) for _ in range(3)]
            depth = ctx.depth_texture(size, samples=ms)
            if not ms:  # multisample textures have no sampler state (read by texelFetch)
                depth.compare_func = ""  # sampled as plain depth values by later passes
            self._gbuffer = ctx.framebuffer(color_attachments=colors, depth_attachment=depth)
            self._depth_only = ctx.framebuffer(depth_attachment=depth)
            self._depth_clean = False
        return self._gbuffer

    def execute(self, frame) -> None:
        """Fill the G-buffer, then let the transparency method store the transparent fragments."""
        mgl = moderngl
        fbo = self.gbuffer(frame)
        fbo.use()
        fbo.depth_mask = True
        self.ctx.disable(mgl.BLEND | mgl.CULL_FACE)
        self.ctx.enable(mgl.DEPTH_TEST)
        self.ctx.depth_func = "<"
        has_opaque = any(not d.transparent for d in frame.draws)
        host = frame.resources["host_layer"]
        # An empty frame needs no depth: the composite then reads none. Depth only: the composite
        # reads the colour targets only where an opaque surface was drawn. A depth buffer nothing
        # has written since its last clear is not cleared again: only opaque draws write it
        # (transparent passes test against it with writes off), and on the H100 the clear took
        # 0.07 ms of a 1024² frame, 0.25 ms at 4 samples (docs/decisions.md, 2026-11-25 "the G-buffer depth").
        # Over the host's layer every pixel starts at the host's depth instead (no clear needed).
        if host is not None:
            self._enter_host_layer(host)
            self._depth_clean = False
        elif frame.draws and (has_opaque or not self._depth_clean):
            self._depth_only.depth_mask = True  # transparent passes leave it off
            self._depth_only.clear(depth=1.0)
            fbo.use()  # clearing bound the depth-only framebuffer
            self._depth_clean = True
        if has_opaque:
            frame.draw_opaque()
            self._depth_clean = False
        frame.resources["gbuffer"] = GBuffer(
            fbo=fbo,
            depth_only=self._depth_only,
            albedo=fbo.color_attachments[0],
            normal=fbo.color_attachments[1],
            material=fbo.color_attachments[2],
            depth=fbo.depth_attachment,
            has_opaque=has_opaque or host is not None,
            samples=self._samples,
            host_layer=host is not None,
        )
        aa = self.device.antialiasing
        frame.stats["antialiasing"] = {
            "samples": self._samples,
            **({"asked": aa.asked} if aa.asked != self._samples else {}),
            **({"supersample": aa.supersample} if aa.supersample > 1 else {}),
        }
        frame.stats.memory("gbuffer", frame.pixel_count * (3 * 8 + 4) * self._samples)
        method = frame.method
        has_transparency = bool(frame.transparent_draws)
        store = TransparentStore(method) if has_transparency else None
        frame.resources["transparent"] = store
        if has_transparency and not method.geometry_in_composite:
            method.prepare(frame)
            method.render_transparent(frame)
            self.ctx.memory_barrier()
            store.nodes_by_tile = frame.raster.nodes_by_tile(frame)
        elif not has_transparency:
            frame.stats["fragments"] = {"stored": 0}
        self.ctx.depth_func = "<"

    def _enter_host_layer(self, host) -> None:
        """Write the host's depth into every pixel (and sample) of the G-buffer, its albedo marked as the host's.

        A full-screen draw rather than a blit: a blit cannot go from one sample to several, and the
        colour targets must be marked in the same go (the composite shades only guaca's surfaces).
        """
        prog = self.device.programs.program(
            {
                "vertex_shader": ("composite/fullscreen.vert.j2", {}),
                "fragment_shader": (
                    "gbuffer/host_layer.frag.j2",
                    {"host_mark": HOST_MARK, "supersample": self.device.antialiasing.supersample},
                ),
            },
            label="host_layer",
        )
        host.depth.use(location=Texture.HOST_DEPTH)
        self.ctx.depth_func = "1"  # every pixel takes the host's depth, whatever the buffer held
        self.device.fullscreen(prog)
        self.ctx.depth_func = "<"

    def collect(self, frame) -> None:
        """The method's and the compute rasterizer's counters (an overflow asks for the frame again)."""
        method = frame.method
        if frame.transparent_draws and not method.geometry_in_composite:
            frame.rerender = method.finish(frame)
            frame.rerender = frame.raster.finish(frame) or frame.rerender

    def release(self) -> None:
        """Free the G-buffer."""
        if self._gbuffer is not None:
            for t in self._gbuffer.color_attachments:
                t.release()
            self._gbuffer.depth_attachment.release()
            self._gbuffer.release()
            self._depth_only.release()
            self._gbuffer = None
