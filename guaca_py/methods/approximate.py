"""Approximate forward-blending references: unsorted and object-sorted alpha blending, weighted blended OIT.

These methods shade each transparent fragment while it is drawn (with the composite's shared
shade_surface and the frame's culled lights, hence `geometry_in_composite`) and blend it into
accumulation targets that test against the G-buffer depth; the composite then puts the
accumulated layer, as premultiplied color and coverage, in front of the shaded opaque surface.
"""

from __future__ import annotations

import math

import numpy as np

from ..gpu_timer import SamplesQuery
from ..pipeline.settings import Setting
from ..shaders import set_uniform
from ..shaders.slots import Buffer, Texture
from .base import TransparencyMethod

_FILL_GROUPS_MAX = 4096


def fill_uint_buffer(frame, buffer, count: int, value: int) -> None:
    """Set the first `count` uint words of `buffer` to `value` on the GPU."""
    prog = frame.renderer.shaders.compute("approx/fill.comp.j2")
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


class ForwardBlendMethod(TransparencyMethod):
    """Shared machinery: accumulation targets on the G-buffer depth, in-place shading, fragment counts."""

    exact = False
    geometry_in_composite = True
    antialiasing_refusal = "it blends in hardware into one colour per pixel, with no per-sample storage"
    blend = "over"  # template variant of approx/blend_fragment.glsl.j2
    accum_dtype = "f4"

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self._phase = "composite"  # template variant: geometry phases add the lighting variables
        self._shading: dict = {}
        self._fbo = self._clear = None
        self._targets: list = []
        self._key = None
        self._pixels = 0
        # samples-passed queries by (count name, frame parity): a frame loop without read-back reads
        # the previous frame's, finished by then, instead of waiting for this frame's (finish)
        self._queries: dict = {}
        self._parity = 0
        self._counted: dict = {}  # this frame's queries by count name
        self._previous: dict | None = None  # the previous frame's, in a loop without read-back

    # ------------------------------------------------------------------ storage
    def _target_specs(self) -> list[tuple[int, str, tuple]]:
        """(components, dtype, clear value) of each accumulation target."""
        return [(4, self.accum_dtype, (0.0, 0.0, 0.0, 0.0))]

    def _alloc(self, frame) -> None:
        depth = frame.resources["gbuffer"]["depth"]
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
        """Allocate (on resolution change) and clear the accumulation targets."""
        self._shading = frame.shading_vars()
        self._alloc(frame)
        for fbo, (_, _, value) in zip(self._clear, self._target_specs()):
            fbo.clear(*value)

    # ------------------------------------------------------------------ drawing
    def draw_order(self, frame) -> list | None:
        """Transparent draws in the order to submit them (None: as listed)."""
        return None

    def blend_state(self, mgl) -> tuple:
        """Blend factors (src rgb, dst rgb, src alpha, dst alpha) of the accumulation."""
        if self.blend == "over":  # premultiplied back-to-front "over"
            return (mgl.ONE, mgl.ONE_MINUS_SRC_ALPHA, mgl.ONE, mgl.ONE_MINUS_SRC_ALPHA)
        # additive sums in rgb, multiplicative revealage in alpha (one state for both targets)
        return (mgl.ONE, mgl.ONE, mgl.ZERO, mgl.ONE_MINUS_SRC_ALPHA)

    def _blended_pass(self, frame, uniforms: dict | None = None) -> None:
        """Draw the transparent list once into the accumulation targets, counting fragments as 'blended'."""
        mgl = frame.renderer.moderngl
        ctx = frame.ctx
        self._fbo.depth_mask = False
        self._fbo.use()
        ctx.enable(mgl.DEPTH_TEST | mgl.BLEND)
        ctx.depth_func = "<"
        ctx.blend_equation = mgl.FUNC_ADD
        ctx.blend_func = self.blend_state(mgl)
        try:
            with self.samples_query(ctx, "blended"):
                frame.draw_transparent(uniforms or {}, per_program=frame.bind_lights, order=self.draw_order(frame))
        finally:
            ctx.disable(mgl.BLEND)
            ctx.blend_func = mgl.DEFAULT_BLENDING
            self._fbo.depth_mask = True

    def samples_query(self, ctx, name: str):
        """This frame's samples-passed query for the count `name` (read in finish, not here: reading waits)."""
        key = (name, self._parity)
        if key not in self._queries:
            self._queries[key] = SamplesQuery(ctx)
        self._counted[name] = self._queries[key]
        return self._queries[key]

    def counts(self, frame) -> dict[str, int]:
        """Fragment counts by name: this frame's, or in a loop without read-back the previous frame's.

        Reading a query waits for the GPU to finish its block; in the middle of a frame that left
        the GPU idle while the CPU submitted the rest (a sync per frame in an application's loop).
        """
        now, self._counted, self._parity = self._counted, {}, self._parity ^ 1
        if frame.late_counters and self._previous is not None:
            late, self._previous = self._previous, now
            frame.stats["fragments_of"] = "previous frame"
            return {name: int(q.samples) for name, q in late.items()}
        self._previous = now if frame.late_counters else None
        return {name: int(q.samples) for name, q in now.items()}

    def render_transparent(self, frame) -> None:
        """One geometry pass, shading and blending every transparent fragment in front of the opaque depth."""
        self._phase = "geometry"
        try:
            self._blended_pass(frame)
        finally:
            self._phase = "composite"

    def finish(self, frame) -> bool:
        """Report fragments blended (nothing is dropped or merged: blending keeps every fragment)."""
        counts = self.counts(frame)
        blended = counts.pop("blended", 0)
        frame.stats["fragments"] = {"stored": blended, "blended": blended, "dropped": 0, "merged": 0, **counts}
        frame.stats["geometry_passes"] = int(self.geometry_passes)
        return False

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """In-place shading and blending."""
        return "approx/blend_fragment.glsl.j2"

    def resolve_template(self) -> str:
        """Reads the accumulation targets."""
        return "approx/blend_resolve.glsl.j2"

    def template_vars(self) -> dict:
        """Blend variant; while drawing, the lighting variables of shading/lighting.glsl.j2 too."""
        v = {"approx_blend": self.blend, "approx_phase": self._phase, "approx_normalize": True}
        if self._phase != "composite":  # the composite adds its own lighting variables
            v.update(self._shading)
        return v

    def bind_composite(self, frame, program) -> None:
        """Accumulation targets on the method's texture units."""
        for unit, name, tex in zip(
            (Texture.APPROX_ACCUM, Texture.APPROX_WEIGHT), ("gua_approx_accum", "gua_approx_weight"), self._targets
        ):
            tex.use(location=unit)
            set_uniform(program, name, unit)

    def memory(self) -> dict:
        """Bytes of the accumulation targets (dense: every byte allocated is used)."""
        total = sum(self._pixels * n * (4 if dt == "f4" else 2) for n, dt, _ in self._target_specs())
        return {"blend_accum": total, "blend_accum_used": total} if self._targets else {}

    def _release_targets(self) -> None:
        for f in self._clear or []:
            f.release()
        if self._fbo is not None:
            self._fbo.release()
        for t in self._targets:
            t.release()
        self._fbo, self._clear, self._targets, self._key = None, None, [], None

    def release(self) -> None:
        """Free the targets and the queries."""
        self._release_targets()
        for q in self._queries.values():
            q.release()
        self._queries.clear()
        self._counted, self._previous = {}, None


class UnsortedBlend(ForwardBlendMethod):
    """Hardware alpha blending in submission order: the floor (exact for back-to-front, non-crossing layers)."""

    id = "unsorted_blend"
    summary = "back-to-front 'over' blending in submission order, no sorting (approximate floor)"


class ObjectSortedBlend(ForwardBlendMethod):
    """Blending of draws sorted back to front by bounding-box centre distance (exact for separable layers)."""

    id = "object_sorted_blend"
    summary = "'over' blending of draws sorted back to front by world bounding-box centre distance"

    def draw_order(self, frame) -> list:
        """Farthest bounding-box centre first; equal distances keep submission order."""
        eye = frame.camera_position
        draws = frame.transparent_draws
        dist = [float(np.linalg.norm(world_bbox_centre(d) - eye)) for d in draws]
        return [draws[i] for i in sorted(range(len(draws)), key=lambda i: -dist[i])]


def _weights(v) -> str | None:
    return None if v in ("eq7", "eq8", "eq9", "eq10") else f"must be eq7, eq8, eq9 or eq10, got {v!r}"


class WeightedBlended(ForwardBlendMethod):
    """Weighted blended OIT (McGuire & Bavoil, JCGT 2013): weighted average color, exact coverage."""

    id = "weighted_blended"
    blend = "weighted"
    summary = "weighted blended OIT: depth-weighted average color, exact revealage (McGuire & Bavoil 2013)"
    SETTINGS = {
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
    }

    @property
    def accum_dtype(self) -> str:
        """Accumulation texture dtype from the setting."""
        return "f2" if self.settings["accum_format"] == "rgba16f" else "f4"

    def _target_specs(self):
        # target 0: rgb sum of w*color, a revealage (starts at 1); target 1: r sum of weights
        return [(4, self.accum_dtype, (0.0, 0.0, 0.0, 1.0)), (1, self.accum_dtype, (0.0, 0.0, 0.0, 0.0))]

    def template_vars(self) -> dict:
        """Weight function on top of the shared variables."""
        return {**super().template_vars(), "wboit_weight": self.settings["weight"]}
