"""Peeling: one class for every peeling method, configured by a record each; depth and dual depth peeling.

Peeling shades each peeled layer, so these methods run their geometry passes at the start of the
composite pass (`geometry_in_composite`). A depth peeling pass keeps, per pixel, the nearest
remaining fragment by its exact key (window depth, tie id) together with its packed shading
inputs; a compute step then shades that layer with the shared shade_surface, blends it under the
front accumulation and moves the pixel's bounds. A dual depth peeling pass (Bavoil and Myers'
structure) shades the fragments at the pixel's two bounds in place, into the front and back
accumulations, and keeps the nearest and farthest keys between them, which its step makes the
next bounds. Only fragments in front of the G-buffer depth are peeled; the composite puts the
accumulated layers in front of the shaded opaque surface.

Why not the hardware depth test: moderngl only makes 24-bit depth textures, and an exact order
with deterministic ties needs a 64-bit (depth, tie) comparison. The per-pass "depth buffer" is
therefore emulated in colour targets read and written in primitive order (framebuffer fetch, or
images inside an ordered fragment shader interlock).

The peeling methods differ in their per-pixel state (the steps' slots; the geometry phases order
those or textures of their own, `PHASES`), in
the compute steps' variant and in their loop of geometry passes and steps: `PeelKind` records
them, the loop as a plain function of the method (hybrid and coherent layer peeling's in
peeling_coherent.py, multi-layer peeling's with its node pool in peeling_multilayer.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import moderngl

from ..errors import UnsupportedMethodError
from ..gpu_counters import CounterBlock
from ..pipeline.settings import Setting
from ..registry import register
from ..shaders import set_uniform
from ..shaders.slots import Buffer, Image, Texture
from .base import MethodSpec, TransparencyMethod

# Counter words of peeling/counters.glsl.j2, in order.
COUNTERS = (
    "in_range",
    "peeled",
    "composited",
    "overflow",
    "alloc",
    "guard",
    "saturated",
    "rejected",
    "left",
    "active",
    "hidden",
)
EMPTY_NEAR = "uvec4(GUA_INF, 0u, 0u, 0u)"  # slot clears (GLSL) of step.comp.j2's init step
EMPTY_NEAR_TIE = "uvec4(0u, 0u, 0u, GUA_TIE_MAX)"
ZERO = "uvec4(0u)"
EMPTY_NEXT = "GUA_DUAL_EMPTY_NEXT"  # dual: nearest key +inf, farthest -1
# the steps of peeling/step.comp.j2 that shade a peeled layer: only they get the lighting code and the lights
# (dual's passes shade in place; every other step only moves keys, clears or counts)
SHADING_STEPS = frozenset(("nearest", "multilayer", "coherent_after_5"))
_FETCH_EXT = "#extension GL_EXT_shader_framebuffer_fetch : require\n"
_INTERLOCK_EXT = "#extension GL_ARB_fragment_shader_interlock : require\n"


def _non_negative(v) -> str | None:
    return None if v >= 0 else f"must be >= 0 (0 = unlimited), got {v}"


# the settings of every peeling method
PEEL_SETTINGS = {
    "max_passes": Setting(
        (int,),
        0,
        "cap on geometry passes per frame (0 = unlimited); layers left when it stops are reported as truncated",
        check=_non_negative,
    ),
    "ordering": Setting(
        (str,),
        "auto",
        "how a pass updates per-pixel state in primitive order: "
        "'fetch' (EXT_shader_framebuffer_fetch), 'interlock' (ARB_fragment_shader_interlock) "
        "or 'auto'",
        choices=("auto", "fetch", "interlock"),
    ),
}


def ordering_backend(setting: str, caps) -> str | None:
    """'fetch' or 'interlock' for an ordering setting on this device, or None when it has neither."""
    fetch = bool(getattr(caps, "framebuffer_fetch", False))
    if setting == "fetch":
        return "fetch" if fetch else None
    if setting == "interlock":
        return "interlock" if caps.fragment_interlock else None
    return "fetch" if fetch else ("interlock" if caps.fragment_interlock else None)


@dataclass(frozen=True)
class Phase:
    """A geometry phase (`peel_phase` of peeling/fragment.glsl.j2): the state its passes order, whether they shade."""

    # textures its passes read and write in primitive order (fetch or interlock): "slots" for the
    # method's slots (what its steps read next), else the textures named; none: not an ordered phase
    ordered: tuple[str, ...] | Literal["slots"] = ()
    shades: bool = False  # shades fragments where they are drawn: needs the lighting variables and the lights


# every geometry phase of the peeling methods
PHASES = {
    "nearest": Phase("slots"),  # depth and hybrid peeling: the nearest remaining fragment's payload
    "stencil": Phase("slots"),  # coherent's counting passes: emulated depth and stencil, a payload
    "multilayer": Phase(),  # atomics on the node pool, in any order
    "composite_range": Phase(shades=True),  # blended under the front accumulation by the hardware
    # dual: the bounds, the keys between them and both accumulations (the first pass: the second keys too)
    "dual_first": Phase(("bounds", "next", "acc_front", "acc_back", "second"), shades=True),
    # (later passes only read the bounds, but as a target they cost llvmpipe half what a sampled texture
    # does: docs/decisions.md, 2026-11-28 "dual depth peeling's bounds")
    "dual": Phase(("bounds", "next", "acc_front", "acc_back"), shades=True),
}


@dataclass(frozen=True)
class PeelKind:
    """What one peeling method chooses: its steps' per-pixel state, its steps and its loop."""

    step_method: str  # `method` variable of peeling/step.comp.j2
    render: Callable[[Peeling, Any], None]  # geometry passes and steps until done: render(method, frame)
    # per-pixel state the steps read and write (gua_slotN of step.comp.j2), in slot order: (texture
    # name, components of uint32, value the init step clears it to in GLSL); the geometry phases
    # whose `ordered` is "slots" read and write it in primitive order too
    slots: tuple[tuple[str, int, str], ...] = ()
    has_back: bool = False  # a back accumulation (dual)
    has_range: bool = False  # a per-pixel compositing range texture (hybrid, coherent)
    needs_ordering: bool = True  # geometry passes read-modify-write per-pixel state in primitive order
    # dual: the init step starts each pixel's upper bound at its opaque depth (the first pass tests only it)
    upper_opaque: bool = False
    # storage of its own beside the textures (multi-layer peeling's node pool): made as storage(method)
    storage: Callable[[Peeling], Any] | None = None


# the payload (8 words) of each pixel's nearest remaining fragment: the emulated depth buffer of
# depth peeling (word 0 depth, word 7 tie); empty is key (+inf, max tie)
NEAREST_PAYLOAD = (("payload0", 4, EMPTY_NEAR), ("payload1", 4, EMPTY_NEAR_TIE))


class Peeling(TransparencyMethod):
    """Per-pixel state textures, ordered geometry passes, compute steps, counters and stats of every peeling method."""

    exact = True
    geometry_in_composite = True
    antialiasing_refusal = "it peels one depth per pixel and pass, so a layer cannot differ between samples"

    def __init__(self, spec, settings, caps):
        super().__init__(spec, settings, caps)
        self.kind: PeelKind = spec.options
        self.step_method = self.kind.step_method
        self.has_back, self.has_range = self.kind.has_back, self.kind.has_range
        needs_ordering = self.kind.needs_ordering
        self.order = ordering_backend(settings.get("ordering", "auto"), caps) if needs_ordering else None
        if needs_ordering and self.order is None:
            raise UnsupportedMethodError(
                f"method '{self.id}' with ordering '{settings.get('ordering')}' cannot run "
                f"on {caps.gl_renderer}: the device lacks that extension"
            )
        self._phase = "composite"
        self._shading: dict = {}
        self._tex: dict = {}
        self._size = None
        self._counters = None
        self._fbos: dict = {}
        self._dummy = None
        self.stats: dict = {}  # this frame's statistics, reported by finish()
        self.passes = 0
        self.storage = self.kind.storage(self) if self.kind.storage else None

    @classmethod
    def unsupported_reason(cls, caps, options) -> str | None:
        """Peeling needs ordered per-pixel read-modify-write (framebuffer fetch or fragment shader interlock)."""
        if options.needs_ordering and ordering_backend("auto", caps) is None:
            return (
                "needs GL_EXT_shader_framebuffer_fetch or GL_ARB_fragment_shader_interlock to keep the "
                "exact (depth, tie) test of each peeling pass in primitive order"
            )
        return None

    # ------------------------------------------------------------------ storage
    def texture_specs(self) -> dict[str, tuple[int, str]]:
        """Per-pixel textures: name -> (components, dtype)."""
        specs = {"acc_front": (4, "f4"), "bounds": (4, "u4")}
        if self.has_back:
            specs["acc_back"] = (4, "f4")
        if self.has_range:
            specs["range"] = (4, "u4")
        specs.update((name, (components, "u4")) for name, components, _ in self.kind.slots)
        return specs

    def slot_names(self) -> list[str]:
        """Textures holding the per-pixel state of the steps, in slot order."""
        return [name for name, _, _ in self.kind.slots]

    def slot_clears(self) -> list[str]:
        """GLSL values the init step writes into each slot."""
        return [clear for _, _, clear in self.kind.slots]

    def _alloc(self, frame) -> None:
        size = (frame.width, frame.height)
        if self._size == size and self._tex:
            return
        self._release_textures()
        mgl = moderngl
        for name, (comps, dtype) in self.texture_specs().items():
            t = frame.ctx.texture(size, comps, dtype=dtype)
            t.filter = (mgl.NEAREST, mgl.NEAREST)
            t.repeat_x = t.repeat_y = False
            self._tex[name] = t
        self._size = size

    def _fbo(self, frame, key: str, names: list[str]):
        """Framebuffer with the named textures as colour targets (cached per resolution)."""
        if key not in self._fbos:
            self._fbos[key] = frame.ctx.framebuffer(color_attachments=[self._tex[n] for n in names])
        return self._fbos[key]

    def _dummy_fbo(self, frame):
        """A target of frame size for passes whose state lives in images (interlock): nothing is written to it."""
        if self._dummy is None:
            rb = frame.ctx.renderbuffer(self._size, 1, dtype="f1")
            self._dummy = frame.ctx.framebuffer(color_attachments=[rb])
        return self._dummy

    def _counter_buffer(self, frame):
        if self._counters is None:
            self._counters = CounterBlock(frame.ctx, COUNTERS)
        return self._counters

    def reset_counters(self, alloc: int = 0) -> None:
        """Zero the counters (the node allocator starts at `alloc`)."""
        self._counters.reset(alloc=alloc)

    def read_counters(self) -> dict:
        """Counter words as a dict."""
        return self._counters.read()

    # ------------------------------------------------------------------ frame
    def prepare(self, frame) -> None:
        """Allocate the per-pixel state and reset it (accumulations, bounds, slots)."""
        if self.storage is not None:
            self.storage.prepare(frame)
        self._shading = frame.shading_vars()
        self._alloc(frame)
        self._counter_buffer(frame)
        self.reset_counters()
        self.passes = 0
        self.stats = {"peeled": 0, "composited": 0, "truncated": 0, "saturated_pixels": 0, "iterations": 0}
        self._warnings: list[str] = []
        self.step(frame, "init")

    def step(self, frame, name: str) -> None:
        """Run one compute step of peeling/step.comp.j2 over every pixel."""
        slots = self.slot_names()
        shades = name in SHADING_STEPS
        prog = frame.programs.compute(
            "peeling/step.comp.j2",
            method=self.step_method,
            step=name,
            shades=shades,
            has_back=self.has_back,
            has_range=self.has_range,
            slot_formats=[self._image_format(n) for n in slots],
            slot_clear=self.slot_clears(),
            **self.step_vars(),
            **(self._shading if shades else {}),
        )
        frame.set_frame_uniforms(prog)
        if shades:
            frame.bind_lights(prog)
        set_uniform(prog, "gua_threshold", self.composite_threshold())
        if set_uniform(prog, "gua_peel_opaque", Texture.PEEL_OPAQUE):
            frame.resources["gbuffer"].depth.use(location=Texture.PEEL_OPAQUE)
        self._bind_step_storage(frame)
        units = {
            "acc_front": Image.PEEL_ACC_FRONT,
            "acc_back": Image.PEEL_ACC_BACK,
            "bounds": Image.PEEL_BOUNDS,
            "range": Image.PEEL_RANGE,
        }
        for name_, unit in units.items():
            if name_ in self._tex:
                self._tex[name_].bind_to_image(unit, read=True, write=True)
        for i, n in enumerate(slots):
            self._tex[n].bind_to_image(Image.PEEL_STEP_SLOTS + i, read=True, write=True)
        self._counters.bind(Buffer.PEEL_COUNTERS)
        prog.run(math.ceil(frame.width / 8), math.ceil(frame.height / 8), 1)
        frame.ctx.memory_barrier()

    def step_vars(self) -> dict:
        """Extra template variables of the compute steps (and of the geometry phases)."""
        v = {"upper_opaque": True} if self.kind.upper_opaque else {}
        if self.storage is not None:
            v.update(self.storage.step_vars())
        return v

    def _bind_step_storage(self, frame) -> None:
        """Bind method buffers the steps read (multi-layer pool)."""
        if self.storage is not None:
            self.storage.bind()

    def _image_format(self, name: str) -> str:
        comps, dtype = self.texture_specs()[name]
        return {(4, "u4"): "rgba32ui", (1, "u4"): "r32ui", (4, "f4"): "rgba32f"}[(comps, dtype)]

    def _common_uniforms(self, frame) -> dict:
        g = frame.resources["gbuffer"]
        if "bounds" not in self.phase_slots(self._phase):  # never sample a texture the pass renders to
            self._tex["bounds"].use(location=Texture.PEEL_BOUNDS)
        g.depth.use(location=Texture.PEEL_OPAQUE)
        if "range" in self._tex:
            self._tex["range"].use(location=Texture.PEEL_RANGE)
        self._counters.bind(Buffer.PEEL_COUNTERS)
        return {
            "gua_peel_bounds": Texture.PEEL_BOUNDS,
            "gua_peel_opaque": Texture.PEEL_OPAQUE,
            "gua_peel_range": Texture.PEEL_RANGE,
        }

    def geometry_pass(self, frame, phase: str, draws=None, uniforms: dict | None = None) -> None:
        """One pass over the transparent draws (or `draws`) that updates the phase's ordered state in primitive order."""
        mgl = moderngl
        ctx = frame.ctx
        ordered = self.phase_slots(phase)
        if self.order == "fetch" and ordered:
            self._fbo(frame, phase, ordered).use()
        else:
            self._dummy_fbo(frame).use()
            for i, n in enumerate(ordered):
                self._tex[n].bind_to_image(Image.PEEL_ORDERED_SLOTS + i, read=True, write=True)
        ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE)
        # With blending and depth test both off, llvmpipe takes a draw that covers a whole 64x64
        # tile for opaque and discards the tile's earlier draws, their image and buffer writes
        # included (multi-layer peeling lost every quad but the last above 384x384); blending as
        # (ONE, ZERO) writes the same colour and keeps every draw.
        ctx.enable(mgl.BLEND)
        ctx.blend_func = (mgl.ONE, mgl.ZERO)
        self._draw(frame, phase, draws, uniforms)

    def composite_range_pass(self, frame, draws=None) -> None:
        """Shade the fragments inside each pixel's range in place and blend them under the front accumulation."""
        mgl = moderngl
        ctx = frame.ctx
        self._fbo(frame, "composite_range", ["acc_front"]).use()
        ctx.disable(mgl.DEPTH_TEST | mgl.CULL_FACE)
        ctx.enable(mgl.BLEND)
        ctx.blend_equation = mgl.FUNC_ADD
        ctx.blend_func = (mgl.ONE_MINUS_DST_ALPHA, mgl.ONE)  # front-to-back "under", premultiplied
        self._draw(frame, "composite_range", draws)

    def _draw(self, frame, phase: str, draws, uniforms: dict | None = None) -> None:
        """Draw the transparent draws (or `draws`) as `phase` with the blending set up, then count the pass."""
        mgl = moderngl
        ctx = frame.ctx
        self._phase = phase  # before the uniforms: they depend on the phase's ordered state
        try:
            lights = frame.bind_lights if PHASES[phase].shades else None
            all_uniforms = {**self._common_uniforms(frame), **(uniforms or {})}
            frame.draw_transparent(all_uniforms, per_program=lights, order=draws)
        finally:
            self._phase = "composite"
            ctx.disable(mgl.BLEND)
            ctx.blend_func = mgl.DEFAULT_BLENDING
        ctx.memory_barrier()
        self.passes += 1

    def cap_reached(self, needed: int = 1) -> bool:
        """Would `needed` more geometry passes exceed max_passes?"""
        cap = int(self.settings.get("max_passes", 0))
        return cap > 0 and self.passes + needed > cap

    def truncate(self, left: int) -> None:
        """Record that the pass cap stopped peeling with `left` fragments not peeled, and warn."""
        self.stats["truncated"] = left
        self.warn(
            f"{self.id}: max_passes={self.settings['max_passes']} stopped peeling with {left} fragments "
            "(at least one more layer) not peeled; the image misses them"
        )

    def warn(self, text: str) -> None:
        """Add a warning to this frame's stats."""
        self._warnings.append(text)

    def render_transparent(self, frame) -> None:
        """The method's loop of geometry passes and steps (PeelKind.render)."""
        self.kind.render(self, frame)

    def finish(self, frame) -> bool:
        """Report passes, fragments, memory use and warnings."""
        s = self.stats
        frame.stats["geometry_passes"] = self.passes
        frame.stats["fragments"] = {"stored": s["peeled"] + s["composited"], **s}
        frame.stats["peeling"] = {"ordering": self.order, "iterations": s["iterations"]}
        if self._warnings:
            frame.stats.setdefault("warnings", []).extend(self._warnings)
        return False

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """Geometry-phase code, switched by the `peel_phase` variable."""
        return "peeling/fragment.glsl.j2"

    def resolve_template(self) -> str:
        """Reads the accumulations."""
        return "peeling/resolve.glsl.j2"

    def template_vars(self) -> dict:
        """Phase of the pass being drawn (part of the program key); geometry phases add their layout."""
        if self._phase == "composite":
            return {"peel_phase": "composite", "peel_back": self.has_back}
        ordered = self.phase_slots(self._phase)
        shades = PHASES[self._phase].shades
        v = {
            "peel_phase": self._phase,
            "peel_order": self.order or "none",
            "ord_formats": [self._image_format(n) for n in ordered],
            "ord_names": ordered,  # GUA_ORD_<NAME>: each texture's slot in peeling/ordered.glsl.j2
            "fragment_interlock": self.order == "interlock" and bool(ordered),
            "peel_shades": shades,
        }
        if shades:
            v.update(self._shading)
        v.update(self.step_vars())
        return v

    def phase_slots(self, phase: str) -> list[str]:
        """Textures a geometry phase reads and writes in primitive order (none: not an ordered phase)."""
        ordered = PHASES[phase].ordered
        return self.slot_names() if ordered == "slots" else list(ordered)

    def extensions(self) -> str:
        """Framebuffer fetch or interlock, whichever orders the passes here."""
        return {"fetch": _FETCH_EXT, "interlock": _INTERLOCK_EXT}.get(self.order, "")

    def bind_composite(self, frame, program) -> None:
        """Accumulations on the method's texture units."""
        for unit, name in ((Texture.PEEL_FRONT, "acc_front"), (Texture.PEEL_BACK, "acc_back")):
            uname = "gua_peel_front" if name == "acc_front" else "gua_peel_back"
            if name in self._tex and set_uniform(program, uname, unit):
                self._tex[name].use(location=unit)

    def memory(self) -> dict:
        """Bytes of every texture and buffer; dense per-pixel state is fully used."""
        out = {}
        for name, t in self._tex.items():
            comps, dtype = self.texture_specs()[name]
            nbytes = t.width * t.height * comps * 4
            out[f"peel_{name}"] = nbytes
            out[f"peel_{name}_used"] = nbytes
        if self._counters is not None:
            out["peel_counters"] = out["peel_counters_used"] = self._counters.buffer.size
        if self.storage is not None:
            out.update(self.storage.memory())
        return out

    def _release_textures(self) -> None:
        for f in self._fbos.values():
            f.release()
        self._fbos = {}
        if self._dummy is not None:
            for a in self._dummy.color_attachments:
                a.release()
            self._dummy.release()
            self._dummy = None
        for t in self._tex.values():
            t.release()
        self._tex = {}
        self._size = None

    def release(self) -> None:
        """Free textures and buffers."""
        self._release_textures()
        if self._counters is not None:
            self._counters.release()
            self._counters = None
        if self.storage is not None:
            self.storage.release()


def peel_layers(m: Peeling, frame) -> None:
    """Depth peeling's loop: geometry pass + step (the nearest layer) until a pass leaves nothing unpeeled.

    The cap reports what is left.
    """
    s = m.stats
    left = 0
    while True:
        if m.cap_reached():
            m.truncate(left)
            break
        m.reset_counters()
        m.geometry_pass(frame, "nearest")
        m.step(frame, "nearest")
        c = m.read_counters()
        s["iterations"] += 1
        s["peeled"] += c["peeled"]
        s["saturated_pixels"] += c["saturated"]
        left = c["in_range"] - c["peeled"]  # fragments the pass saw that are still to peel
        if left == 0:
            break


register("method")(
    MethodSpec(
        "depth_peeling",  # Everitt 2001: one layer per geometry pass, front to back, until nothing is left
        "front-to-back depth peeling, one layer per geometry pass (exact (depth, tie) order)",
        Peeling,
        PeelKind("nearest", peel_layers, NEAREST_PAYLOAD),
        PEEL_SETTINGS,
        geometry_passes=None,
        geometry_passes_rule="layers",
    )
)


def peel_dual(m: Peeling, frame) -> None:
    """Dual depth peeling's loop: a first pass shades each pixel's nearest and farthest layer and finds the
    two after them, each later pass shades the two it was given and finds the next two between them,
    until no pixel has any left.

    Layers peeled = fragments in range - those that early termination hides - those a cap leaves
    (truncated, added up by the step after the last pass the cap allows).
    """
    s = m.stats
    phase = "dual_first"
    in_range = hidden = 0
    while True:
        last = m.cap_reached(needed=2)  # the cap allows this pass and no other
        m.reset_counters()
        m.geometry_pass(frame, phase)
        m.step(frame, "dual_last" if last else "dual")
        c = m.read_counters()
        s["iterations"] += 1
        s["saturated_pixels"] += c["saturated"]
        in_range += c["in_range"]
        hidden += c["hidden"]
        if c["active"] == 0:
            break
        if last:
            m.truncate(c["left"])
            break
        phase = "dual"
    s["peeled"] = in_range - hidden - s["truncated"]


register("method")(
    MethodSpec(
        "dual_depth_peeling",  # Bavoil & Myers 2008: nearest and farthest layer per pass, front under, back over
        "dual depth peeling: nearest and farthest remaining layer per geometry pass",
        Peeling,
        PeelKind(
            "dual",
            peel_dual,
            # the nearest and farthest keys between the bounds (the next pass's bounds); the first
            # pass's second nearest and second farthest; how many fragments are left
            (("next", 4, EMPTY_NEXT), ("second", 4, EMPTY_NEXT), ("left", 1, ZERO)),
            has_back=True,
            upper_opaque=True,
        ),
        PEEL_SETTINGS,
        geometry_passes=None,
        geometry_passes_rule="layers/2",
    )
)
