"""FXAA post pass on display-encoded color."""

from __future__ import annotations

from ..pipeline.settings import NUMBER, Setting, unit_interval
from ..registry import register
from ..shaders import set_uniform
from .base import FullscreenPass


@register("pass")
class FxaaPass(FullscreenPass):
    """Edge-directed anti-aliasing of 'ldr'."""

    name = "fxaa"
    reads = ("ldr",)
    writes = ("ldr",)
    template = "post/fxaa.comp.j2"
    compute = True
    SETTINGS = {
        "edge_threshold": Setting(NUMBER, 0.125, "relative luma contrast that counts as an edge", check=unit_interval)
    }

    def execute(self, frame) -> None:
        """Anti-alias the display image (nothing to do when it holds one colour: it has no edge)."""
        src = frame.resources["ldr"]
        if src.glo in frame.uniform_textures:
            # no luma contrast anywhere: every pixel would store its own texel unchanged
            frame.stats.section("skipped")[self.name] = "the image holds one colour (no edges)"
            return
        prog = self.program(frame)
        set_uniform(prog, "gua_edge_threshold", float(self.settings["edge_threshold"]))
        set_uniform(prog, "gua_resolution", tuple(float(v) for v in frame.output_size))  # after supersampling
        tex = self.run_fullscreen(frame, prog, {"gua_input": src})
        frame.resources["ldr"] = tex
