"""Tone mapping: linear HDR → display-referred 8-bit (exposure, curve, sRGB encoding)."""

from __future__ import annotations

from ..pipeline.settings import NUMBER, Setting, positive
from .base import FullscreenPass


class ToneMappingPass(FullscreenPass):
    """Maps 'hdr' to 'ldr'."""

    name = "tone_mapping"
    reads = ("hdr",)
    writes = ("ldr",)
    template = "post/tone_mapping.comp.j2"
    compute = True
    SETTINGS = {
        "operator": Setting((str,), "aces", "tone curve", choices=("aces", "reinhard", "clamp")),
        "exposure": Setting(NUMBER, 1.0, "linear scale before the curve", check=positive),
        "srgb": Setting((bool,), True, "encode the output as sRGB"),
    }

    def execute(self, frame) -> None:
        """Tone-map the composited color."""
        prog = self.program(frame)
        prog["gua_exposure"] = float(self.settings["exposure"])
        prog["gua_srgb"] = bool(self.settings["srgb"])
        tex = self.run_fullscreen(frame, prog, {"gua_input": frame.resources["hdr"]})
        frame.resources["ldr"] = frame.resources["color"] = tex
