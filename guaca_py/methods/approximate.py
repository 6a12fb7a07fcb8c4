"""Approximate forward blending: unsorted and object-sorted alpha blending, weighted blended OIT and
stochastic transparency, as one class with one record of options each.

These methods shade each transparent fragment while it is drawn (with the composite's shared
shade_surface and the frame's culled lights, hence `geometry_in_composite`) and blend it into
accumulation targets that test against the G-buffer depth; the composite then puts the
accumulated layer, as premultiplied color and coverage, in front of the shaded opaque surface.

Stochastic transparency (Enderton et al. 2010, with the alpha-corrected accumulation pass) draws
twice. S samples per pixel are emulated with S depth words per pixel in a storage buffer
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

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from ..gpu_timer import SamplesQuery
from ..limits import require_bytes
from ..pipeline.settings import Setting
from ..registry import register
from ..shaders import set_uniform
from ..shaders.slots import Buffer, Texture
from .base import MethodSpec, TransparencyMethod

_FILL_GROUPS_MAX = 4096


def fill_uint_buffer(frame, buffer, count: int, value: int) -> None:
    """Set the first `count` uint words of `buffer` to `value` on the GPU."""
    prog = frame.programs.compute("approx/fill.comp.j2")
    buffer.bind_to_storage_buffer(Buffer.FILL_TARGET)
    prog["gua_fill_count"] = count
    prog["gua_fill_value"] = value
    prog.run(max(1, min(_FILL_GROUPS_MAX, math.ceil(count / 256))), 1, 1)
    frame.ctx.memory_barrier()


def world_bbox_centre(draw) -> np.ndarray:
    """Centre of the world-space axis-aligned box around a draw's transformed object-space box."""
    lo, hi = np.min(draw.mesh.positions, axis=0), np.max(draw.mesh.positions, axis=0)
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = corners @ np.asarray(draw.world, dtype=np.float64).T
    world = world[:, :3] / world[:, 3:4]
    return 0.5 * (world.min(axis=0) + world.max(axis=0))


@dataclass(frozen=True)
class BlendKind:
    """How a forward-blending method accumulates and in which order it submits the draws."""

    # "over" (premultiplied back-to-front), "weighted" (McGuire & Bavoil) or "stochastic" (Enderton
    # et al.): the variant of approx/blend_fragment.glsl.j2 and approx/blend_resolve.glsl.j2
    blend: str
    object_sorted: bool = False  # draws back to front by world bounding-box centre distance


class ForwardBlend(TransparencyMethod):
    """Accumulation targets on the G-buffer depth, in-place shading, fragment counts."""

    exact = False
    geometry_in_composite = True
    antialiasing_refusal = "it blends in hardware into one colour per pixel, with no per-sample storage"

    def __init__(self, spec, settings, caps):
        super().__init__(spec, settings, caps)
        self.kind: BlendKind = spec.options
        self.blend = self.kind.blend
        self._phase = "composite"  # template variant: geometry phases add the lighting variables
        self._shading: dict = {}
        self._fbo = self._clear = None
        self._targets: list = []
        self._key = None
        self._pixels = 0
        # samples-passed queries by (count name, view, frame parity): a frame loop without read-back
        # reads the previous frame's of the same view (render_views), finished by then, instead of
        # waiting for this frame's (finish)
        self._queries: dict = {}
        self._parity: dict[int, int] = {}  # per view
        self._counted: dict = {}  # this frame's queries by count name
        self._previous: dict[int, dict] = {}  # per view: the previous frame's, in a loop without read-back
        self._depth = None  # stochastic: S depth words per pixel
        self._depth_pixels = 0

    @property
    def accum_dtype(self) -> str:
        """Accumulation texture dtype (weighted blending: from the accum_format setting)."""
        if self.blend == "weighted" and self.settings["accum_format"] == "rgba16f":
            return "f2"
        return "f4"

    @property
    def samples(self) -> int:
        """S, the coverage samples per pixel of stochastic transparency."""
        return int(self.settings["samples"])

    # ------------------------------------------------------------------ storage
    def _target_specs(self) -> list[tuple[int, str, tuple]]:
        """(components, dtype, clear value) of each accumulation target."""
        if self.blend == "over":
            return [(4, self.accum_dtype, (0.0, 0.0, 0.0, 0.0))]
        # target 0: rgb sum of w*color, a revealage (starts at 1); target 1: r sum of weights
        return [(4, self.accum_dtype, (0.0, 0.0, 0.0, 1.0)), (1, self.accum_dtype, (0.0, 0.0, 0.0, 0.0))]

    def _alloc(self, frame) -> None:
        depth = frame.resources["gbuffer"].depth
        key = (frame.width, frame.height, depth.glo)
        if key == self._key:
            return
        self._release_targets()
        size = (frame.width, frame.height)
        self._targets = [frame.ctx.texture(size, n, dtype=dt) for n, dt, _ in self._target_specs()]
        self._fbo = frame.ctx.framebuffer(color_attachments=self._targets, depth_attachment=depth)
        # separate colour-only framebuffers: clearing must never touch the shared opaque depth
        self._clear = [frame.ctx.framebuffer(color_attachments=[t]) for t in self._targets]
        self._key, self._pixels = key, frame.pixel_count

    def prepare(self, frame) -> None:
        """Allocate (on resolution change) and clear the accumulation targets; stochastic: the depth words, set to 'far'."""
        self._shading = frame.shading_vars()
        self._alloc(frame)
        for fbo, (_, _, value) in zip(self._clear, self._target_specs()):
            fbo.clear(*value)
        if self.blend == "stochastic":
            self._prepare_sample_depths(frame)

    def _prepare_sample_depths(self, frame) -> None:
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

    # ------------------------------------------------------------------ drawing
    def draw_order(self, frame) -> list | None:
        """Transparent draws in the order to submit them (None: as listed); object-sorted: farthest
        bounding-box centre first, equal distances in submission order."""
        if not self.kind.object_sorted:
            return None
        eye = frame.camera_position
        draws = frame.transparent_draws
        dist = [float(np.linalg.norm(world_bbox_centre(d) - eye)) for d in draws]
        return [draws[i] for i in sorted(range(len(draws)), key=lambda i: -dist[i])]

    def blend_state(self, mgl) -> tuple:
        """Blend factors (src rgb, dst rgb, src alpha, dst alpha) of the accumulation."""
        if self.blend == "over":  # premultiplied back-to-front "over"
            return (mgl.ONE, mgl.ONE_MINUS_SRC_ALPHA, mgl.ONE, mgl.ONE_MINUS_SRC_ALPHA)
        # additive sums in rgb, multiplicative revealage in alpha (one state for both targets)
        return (mgl.ONE, mgl.ONE, mgl.ZERO, mgl.ONE_MINUS_SRC_ALPHA)

    def _blended_pass(self, frame, uniforms: dict | None = None) -> None:
        """Draw the transparent list once into the accumulation targets, counting fragments as 'blended'."""
        mgl = moderngl
        ctx = frame.ctx
        self._fbo.depth_mask = False
        self._fbo.use()
        ctx.enable(mgl.DEPTH_TEST | mgl.BLEND)
        ctx.depth_func = "<"
        ctx.blend_equation = mgl.FUNC_ADD
        ctx.blend_func = self.blend_state(mgl)
        try:
            with self.samples_query(frame, "blended"):
                frame.draw_transparent(uniforms or {}, per_program=frame.bind_lights, order=self.draw_order(frame))
        finally:
            ctx.disable(mgl.BLEND)
            ctx.blend_func = mgl.DEFAULT_BLENDING
            self._fbo.depth_mask = True

    def samples_query(self, frame, name: str):
        """This frame's samples-passed query for the count `name` (read in finish, not here: reading waits)."""
        key = (name, frame.view_index, self._parity.get(frame.view_index, 0))
        if key not in self._queries:
            self._queries[key] = SamplesQuery(frame.ctx)
        self._counted[name] = self._queries[key]
        return self._queries[key]

    def counts(self, frame) -> dict[str, int]:
        """Fragment counts by name: this frame's, or in a loop without read-back the previous frame's.

        Reading a query waits for the GPU to finish its block; in the middle of a frame that left
        the GPU idle while the CPU submitted the rest (a sync per frame in an application's loop).
        """
        view = frame.view_index
        now, self._counted = self._counted, {}
        self._parity[view] = self._parity.get(view, 0) ^ 1
        if not frame.late_counters:
            self._previous.clear()  # a later loop starts afresh, not from the counts of older frames
            return {name: int(q.samples) for name, q in now.items()}
        late, self._previous[view] = self._previous.get(view), now
        if late is None:
            return {name: int(q.samples) for name, q in now.items()}
        frame.stats["fragments_of"] = "previous frame"
        return {name: int(q.samples) for name, q in late.items()}

    def render_transparent(self, frame) -> None:
        """One geometry pass, shading and blending every transparent fragment in front of the opaque depth
        (stochastic: a depth pass over the coverage samples first, then the shaded accumulation)."""
        if self.blend == "stochastic":
            self._stochastic_passes(frame)
            return
        self._phase = "geometry"
        try:
            self._blended_pass(frame)
        finally:
            self._phase = "composite"

    def _stochastic_passes(self, frame) -> None:
        """Pass 1 stochastic depth (depth test only), pass 2 shaded accumulation."""
        mgl = moderngl
        ctx = frame.ctx
        uniforms = {"gua_stoch_seed": int(self.settings["seed"]) & 0xFFFFFFFF}
        g = frame.resources["gbuffer"]
        try:
            self._phase = "depth"
            g.depth_only.depth_mask = False
            g.depth_only.use()
            ctx.enable(mgl.DEPTH_TEST)
            ctx.disable(mgl.BLEND)
            ctx.depth_func = "<"
            self._depth.bind_to_storage_buffer(Buffer.STOCHASTIC_DEPTH)
            with self.samples_query(frame, "depth_pass"):  # reported beside 'blended' (finish)
                frame.draw_transparent(uniforms)
            g.depth_only.depth_mask = True
            ctx.memory_barrier()
            self._phase = "accum"
            self._depth.bind_to_storage_buffer(Buffer.STOCHASTIC_DEPTH)
            self._blended_pass(frame, uniforms)
        finally:
            self._phase = "composite"

    def finish(self, frame) -> bool:
        """Report fragments blended (nothing is dropped or merged: blending keeps every fragment)."""
        counts = self.counts(frame)
        blended = counts.pop("blended", 0)
        frame.stats["fragments"] = {"stored": blended, "blended": blended, "dropped": 0, "merged": 0, **counts}
        frame.stats["geometry_passes"] = self.geometry_passes
        return False

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """In-place shading and blending (stochastic: both passes, selected by the phase)."""
        if self.blend == "stochastic":
            return "approx/stochastic_fragment.glsl.j2"
        return "approx/blend_fragment.glsl.j2"

    def resolve_template(self) -> str:
        """Reads the accumulation targets."""
        return "approx/blend_resolve.glsl.j2"

    def template_vars(self) -> dict:
        """Blend variant and its settings; while drawing, the lighting variables of shading/lighting.glsl.j2 too."""
        v = {"approx_blend": self.blend, "approx_phase": self._phase, "approx_normalize": True}
        if self._phase != "composite":  # the composite adds its own lighting variables
            v.update(self._shading)
        if self.blend == "weighted":
            v["wboit_weight"] = self.settings["weight"]
        elif self.blend == "stochastic":
            v.update(samples=self.samples, approx_normalize=bool(self.settings["alpha_correction"]))
        return v

    def bind_composite(self, frame, program) -> None:
        """Accumulation targets on the method's texture units."""
        for unit, name, tex in zip(
            (Texture.APPROX_ACCUM, Texture.APPROX_WEIGHT), ("gua_approx_accum", "gua_approx_weight"), self._targets
        ):
            tex.use(location=unit)
            set_uniform(program, name, unit)

    def memory(self) -> dict:
        """Bytes of the accumulation targets (dense: every byte allocated is used); stochastic: the depth words."""
        total = sum(self._pixels * n * (4 if dt == "f4" else 2) for n, dt, _ in self._target_specs())
        mem = {"blend_accum": total, "blend_accum_used": total} if self._targets else {}
        if self._depth is not None:
            mem["stochastic_depth"] = mem["stochastic_depth_used"] = self._depth_pixels * self.samples * 4
        return mem

    def _release_targets(self) -> None:
        for f in self._clear or []:
            f.release()
        if self._fbo is not None:
            self._fbo.release()
        for t in self._targets:
            t.release()
        self._fbo, self._clear, self._targets, self._key = None, None, [], None

    def release(self) -> None:
        """Free the targets, the queries and the depth words."""
        self._release_targets()
        for q in self._queries.values():
            q.release()
        self._queries.clear()
        self._counted, self._previous = {}, {}
        if self._depth is not None:
            self._depth.release()
            self._depth = None


def _weights(v) -> str | None:
    return None if v in ("eq7", "eq8", "eq9", "eq10") else f"must be eq7, eq8, eq9 or eq10, got {v!r}"


def _samples(v) -> str | None:
    return None if 1 <= v <= 32 else f"must be between 1 and 32, got {v}"


for _spec in (
    # the floor: exact for back-to-front, non-crossing layers
    MethodSpec(
        "unsorted_blend",
        "back-to-front 'over' blending in submission order, no sorting (approximate floor)",
        ForwardBlend,
        BlendKind("over"),
    ),
    # exact for separable layers
    MethodSpec(
        "object_sorted_blend",
        "'over' blending of draws sorted back to front by world bounding-box centre distance",
        ForwardBlend,
        BlendKind("over", object_sorted=True),
    ),
    # McGuire & Bavoil, JCGT 2013: weighted average color, exact coverage
    MethodSpec(
        "weighted_blended",
        "weighted blended OIT: depth-weighted average color, exact revealage (McGuire & Bavoil 2013)",
        ForwardBlend,
        BlendKind("weighted"),
        {
            "weight": Setting(
                (str,),
                "eq7",
                "depth weight function of the paper: eq7, eq8, eq9 (view depth) or eq10 (window depth)",
                check=_weights,
            ),
            "accum_format": Setting(
                (str,),
                "rgba32f",
                "accumulation precision (the paper uses rgba16f; sums of large weights can exceed half-float range)",
                choices=("rgba16f", "rgba32f"),
            ),
        },
    ),
    MethodSpec(
        "stochastic",
        "stochastic transparency: random coverage samples + alpha-corrected accumulation (Enderton 2010)",
        ForwardBlend,
        BlendKind("stochastic"),
        {
            "samples": Setting((int,), 8, "coverage samples per pixel (S, 1..32)", check=_samples),
            "seed": Setting((int,), 0, "seed of the coverage masks (same seed, same image)"),
            "alpha_correction": Setting((bool,), True, "normalize the estimate by the exact total coverage"),
        },
        geometry_passes=2,
    ),
):
    register("method")(_spec)
