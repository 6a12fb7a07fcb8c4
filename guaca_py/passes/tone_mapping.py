"""Tone mapping: linear HDR → display-referred 8-bit (exposure, curve, sRGB encoding)."""

from __future__ import annotations

from ..pipeline.settings import NUMBER, Setting, positive
from ..registry import register
from ..shaders import set_uniform
from .base import FullscreenPass


@register("pass")
class ToneMappingPass(FullscreenPass):
    """Maps 'hdr' to 'ldr', pixel by pixel.

    Per pixel, so when it directly follows the composite and nothing else reads 'hdr', the
    composite applies it to its own output (one full-screen write and read fewer) and this pass
    does nothing: its time is then part of the composite's (stats: `fused_into`).
    """

    name = "tone_mapping"
    reads = ("hdr",)
    writes = ("ldr",)
    template = "post/tone_mapping.comp.j2"
    compute = True
    per_pixel = True
    SETTINGS = {
        "operator": Setting((str,), "aces", "tone curve", choices=("aces", "reinhard", "clamp")),
        "exposure": Setting(NUMBER, 1.0, "linear scale before the curve", check=positive),
        "srgb": Setting((bool,), True, "encode the output as sRGB"),
    }

    def epilogue_vars(self) -> dict:
        """Template variables of post/tone_curve.glsl.j2."""
        return {"operator": self.settings["operator"]}

    def set_epilogue_uniforms(self, prog) -> None:
        """Exposure and sRGB switch of post/tone_curve.glsl.j2."""
        set_uniform(prog, "gua_exposure", float(self.settings["exposure"]))
        set_uniform(prog, "gua_srgb", bool(self.settings["srgb"]))

    def execute(self, frame) -> None:
        """Tone-map the composited color."""
        prog = self.program(frame)
        self.set_epilogue_uniforms(prog)
        src = frame.resources["hdr"]
        tex = self.run_fullscreen(frame, prog, {"gua_input": src})
        if src.glo in frame.uniform_textures:  # per pixel: one colour in, one colour out
            frame.uniform_textures.add(tex.glo)
        frame.resources["ldr"] = tex
