"""Stochastic transparency (Enderton et al. 2010) with the alpha-corrected accumulation pass.

Variant: S samples per pixel are emulated with S depth words per pixel in a storage buffer
(llvmpipe's MSAA stops at 8 samples and the pipeline's G-buffer is single-sampled), so any S up
to 32 works on every device. Pass 1 gives each fragment a random coverage mask of exactly
floor(alpha*S + u) distinct samples (stratified alpha-to-coverage with an unbiased count; masks
are hashed from pixel, draw, primitive and a seed, so images are reproducible) and keeps the
nearest covering depth per sample. Pass 2 shades each fragment, estimates its visibility as the
fraction of samples not covered in front of it, and accumulates alpha*vis*color, alpha*vis and
the revealage prod(1 - alpha); the composite scales the estimated color by the exact coverage
(the paper's alpha correction) or, with `alpha_correction: false`, uses the raw estimate.
"""

from __future__ import annotations

from ..limits import require_bytes
from ..pipeline.settings import Setting
from ..shaders.slots import Buffer
from .approximate import ForwardBlendMethod, fill_uint_buffer


def _samples(v) -> str | None:
    return None if 1 <= v <= 32 else f"must be between 1 and 32, got {v}"


class StochasticTransparency(ForwardBlendMethod):
    """S random coverage samples per pixel, a stochastic depth pass, then an accumulation pass."""

    id = "stochastic"
    blend = "stochastic"
    geometry_passes = "2"
    summary = "stochastic transparency: random coverage samples + alpha-corrected accumulation (Enderton 2010)"
    SETTINGS = {
        "samples": Setting((int,), 8, "coverage samples per pixel (S, 1..32)", check=_samples),
        "seed": Setting((int,), 0, "seed of the coverage masks (same seed, same image)"),
        "alpha_correction": Setting((bool,), True, "normalize the estimate by the exact total coverage"),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self._depth = None
        self._depth_pixels = 0

    @property
    def samples(self) -> int:
        """S."""
        return int(self.settings["samples"])

    def _target_specs(self):
        return [(4, "f4", (0.0, 0.0, 0.0, 1.0)), (1, "f4", (0.0, 0.0, 0.0, 0.0))]

    def prepare(self, frame) -> None:
        """Accumulation targets as the blending methods, plus S depth words per pixel set to 'far'."""
        super().prepare(frame)
        words = frame.pixel_count * self.samples
        if self._depth is None or self._depth_pixels != frame.pixel_count:
            require_bytes(
                self.caps.limits,
                words * 4,
                "transparency.samples",
                f"lower samples (now {self.samples}) or the resolution",
            )
            if self._depth is not None:
                self._depth.release()
            self._depth = frame.ctx.buffer(reserve=words * 4)
            self._depth_pixels = frame.pixel_count
        fill_uint_buffer(frame, self._depth, words, 0xFFFFFFFF)

    def render_transparent(self, frame) -> None:
        """Pass 1 stochastic depth (depth test only), pass 2 shaded accumulation."""
        mgl = frame.renderer.moderngl
        ctx = frame.ctx
        uniforms = {"gua_stoch_seed": int(self.settings["seed"]) & 0xFFFFFFFF}
        g = frame.resources["gbuffer"]
        try:
            self._phase = "depth"
            g["depth_only"].depth_mask = False
            g["depth_only"].use()
            ctx.enable(mgl.DEPTH_TEST)
            ctx.disable(mgl.BLEND)
            ctx.depth_func = "<"
            self._depth.bind_to_storage_buffer(Buffer.STOCHASTIC_DEPTH)
            with self.samples_query(ctx, "depth_pass"):  # reported beside 'blended' (finish)
                frame.draw_transparent(uniforms)
            g["depth_only"].depth_mask = True
            ctx.memory_barrier()
            self._phase = "accum"
            self._depth.bind_to_storage_buffer(Buffer.STOCHASTIC_DEPTH)
            self._blended_pass(frame, uniforms)
        finally:
            self._phase = "composite"

    def template_vars(self) -> dict:
        """Sample count and correction on top of the shared variables."""
        return {
            **super().template_vars(),
            "samples": self.samples,
            "approx_normalize": bool(self.settings["alpha_correction"]),
        }

    def fragment_template(self) -> str:
        """Both passes live in one template, selected by the phase."""
        return "approx/stochastic_fragment.glsl.j2"

    def memory(self) -> dict:
        """Accumulation targets plus the per-sample depth words."""
        mem = super().memory()
        if self._depth is not None:
            mem["stochastic_depth"] = mem["stochastic_depth_used"] = self._depth_pixels * self.samples * 4
        return mem

    def release(self) -> None:
        """Free targets and the depth words."""
        super().release()
        if self._depth is not None:
            self._depth.release()
            self._depth = None
