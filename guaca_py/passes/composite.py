"""Shade-composite pass: shades and blends transparent and opaque fragments front to back."""

from __future__ import annotations

import numpy as np

from ..registry import register
from ..shaders import set_uniform
from .base import FullscreenPass


@register("pass")
class CompositePass(FullscreenPass):
    """Full-screen pass producing linear HDR color ('hdr').

    With a per-pixel epilogue (tone mapping right after it, nothing else reading 'hdr': see
    Renderer._fuse_passes) it applies that to each pixel before storing and writes the
    epilogue's output ('ldr', RGBA8) instead.
    """

    name = "composite"
    reads = ("gbuffer", "transparent", "light_grid")
    writes = ("hdr",)
    target_dtype = "f4"
    compute = True
    template = "composite/shade_composite.comp.j2"
    accepts_epilogue = True

    def __init__(self, renderer, settings):
        super().__init__(renderer, settings)
        # Only tone mapping reads the HDR result when a pipeline has it, and half floats hold more than
        # its 8-bit output resolves (half the bytes to write and read); the linear output stays float32.
        if any(p.name == "tone_mapping" for p in renderer.config.passes):
            self.target_dtype = "f2"

    def set_epilogue(self, epilogue) -> None:
        """Store `epilogue`'s per-pixel result (display-referred 8-bit) instead of the HDR colour."""
        self.release()  # the target changes format
        self.epilogue = epilogue
        self.writes = epilogue.writes
        self.target_dtype = "f1"

    def program(self, frame):
        """Composite program for this method, light lookup and transparency presence."""
        method = frame.resources.get("transparent")
        lights = frame.shading_vars()
        tvars = dict(
            has_transparency=method is not None,
            has_opaque=frame.resources["gbuffer"]["has_opaque"],
            **lights,
            method_extensions=method.resolve_extensions() if method else "",
            method_resolve_template=method.resolve_template() if method else "",
            **(method.template_vars() if method else {}),
        )
        tvars["aa_samples"] = self.renderer.samples  # per-sample accumulators where > 1
        tvars["tone_map"] = self.epilogue is not None
        if self.epilogue is not None:
            tvars.update(self.epilogue.epilogue_vars())
        key = ("composite", tuple(sorted((k, str(v)) for k, v in tvars.items())), method.id if method else None)
        return self.compile(tvars, key)

    def execute(self, frame) -> None:
        """Shade every pixel; writes frame.resources['hdr']."""
        method = frame.resources.get("transparent")
        if method is not None and method.geometry_in_composite:
            self._method_geometry(frame, method)
        prog = self.program(frame)
        frame.set_frame_uniforms(prog)
        self.renderer.pass_named("light_culling").bind(frame, prog)
        if method is not None:
            method.bind_composite(frame, prog)
        threshold = method.composite_threshold() if method else 1.0
        set_uniform(prog, "gua_threshold", threshold)  # compiled out when nothing is composited under the fragments
        set_uniform(prog, "gua_background", np.asarray(frame.scene.background, dtype=np.float32).tobytes())
        if self.epilogue is not None:
            self.epilogue.set_epilogue_uniforms(prog)
        g = frame.resources["gbuffer"]
        tex = self.run_fullscreen(
            frame,
            prog,
            {
                "gbuf_albedo": g["albedo"],
                "gbuf_normal": g["normal"],
                "gbuf_material": g["material"],
                "gbuf_depth": g["depth"],
            },
        )
        if method is not None:
            method.after_composite(frame)
        if method is None and not g["has_opaque"]:  # nothing drawn: the background (or its tone map) everywhere
            frame.uniform_textures.add(tex.glo)
        frame.resources[self.writes[0]] = frame.resources["color"] = tex

    def _method_geometry(self, frame, method) -> None:
        """Methods that shade while drawing run their geometry passes here, after light culling."""
        for _ in range(1 + 16):
            method.prepare(frame)
            method.render_transparent(frame)
            self.ctx.memory_barrier()
            if not method.finish(frame):
                break
            frame.stats["regrown"] = frame.stats.get("regrown", 0) + 1
