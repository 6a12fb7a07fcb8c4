"""k-buffer: the k nearest transparent fragments of each pixel in fixed, sorted per-pixel slots.

Storage is bounded (k slots per pixel) whatever the scene; the insertion is a sorted insert under
a per-pixel 32-bit spin lock (no 64-bit atomics or interlock needed; see
approx/kbuffer_insert.glsl.j2). Fragments beyond k are merged into the farthest slot or dropped
(`overflow`), counted, and reported as a warning. Exact whenever k >= the depth complexity.
"""

from __future__ import annotations

import moderngl

from ..gpu_counters import CounterBlock
from ..limits import require_bytes
from ..pipeline.settings import Setting
from ..registry import register
from ..shaders.slots import Buffer
from .approximate import fill_uint_buffer
from .base import LOCK_SETTING, MethodSpec, TransparencyMethod, resolve_lock

SLOT_BYTES = 32  # the shared 8-word fragment payload (common/payload_pack.glsl.j2)
HEAD_BYTES = 8  # lock + fragment count
COUNTERS = ("inserted", "merged", "dropped", "guard", "filled", "max_count")


def _k(v) -> str | None:
    return None if 1 <= v <= 64 else f"must be between 1 and 64, got {v}"


class KBuffer(TransparencyMethod):
    """Fixed k slots per pixel, kept sorted at insertion under a per-pixel spin lock."""

    exact = False
    antialiasing_refusal = "its k fixed slots per pixel merge fragments whatever samples they cover"

    def __init__(self, spec, settings, caps):
        super().__init__(spec, settings, caps)
        self.lock = resolve_lock(self.id, settings["lock"], caps)
        self._heads = self._slots = self._counters = None
        self._pixels = 0
        self._filled = 0

    @property
    def k(self) -> int:
        """Slots per pixel."""
        return int(self.settings["k"])

    def prepare(self, frame) -> None:
        """Allocate (on resolution change) and reset locks, counts and counters."""
        if self._heads is None or self._pixels != frame.pixel_count:
            require_bytes(
                self.caps.limits,
                frame.pixel_count * self.k * SLOT_BYTES,
                "transparency.k",
                f"lower k (now {self.k}) or the resolution",
            )
            self.release()
            self._pixels = frame.pixel_count
            self._heads = frame.ctx.buffer(reserve=self._pixels * HEAD_BYTES)
            self._slots = frame.ctx.buffer(reserve=self._pixels * self.k * SLOT_BYTES)
            self._counters = CounterBlock(frame.ctx, COUNTERS)
        fill_uint_buffer(frame, self._heads, self._pixels * 2, 0)
        self._counters.reset()

    def _bind(self) -> None:
        self._heads.bind_to_storage_buffer(Buffer.KBUFFER_HEADS)
        self._slots.bind_to_storage_buffer(Buffer.KBUFFER_SLOTS)
        self._counters.bind(Buffer.KBUFFER_COUNTERS)

    def render_transparent(self, frame) -> None:
        """One geometry pass against the opaque depth (writes off); every fragment tries to insert."""
        mgl = moderngl
        g = frame.resources["gbuffer"]
        g.depth_only.depth_mask = False
        g.depth_only.use()
        frame.ctx.enable(mgl.DEPTH_TEST)
        frame.ctx.depth_func = "<"
        self._bind()
        frame.draw_transparent()
        g.depth_only.depth_mask = True
        g.fbo.depth_mask = True

    def finish(self, frame) -> bool:
        """Counters → stats (a frame late in a loop without read-back); overflow and lock-guard drops become warnings."""
        c, _, late = self._counters.latest(frame.late_counters, frame.view_index)
        if late:
            frame.stats["fragments_of"] = "previous frame"
        if frame.late_counters:
            self._counters.stage(view=frame.view_index)
        evicted = c["inserted"] - c["filled"]  # every insert into a full pixel evicts one
        rejected = c["merged"] + c["dropped"] - evicted  # fragments that arrived behind a full pixel
        total = c["inserted"] + rejected + c["guard"]
        self._filled = c["filled"]
        frame.stats["critical_section"] = self.lock
        frame.stats["fragments"] = {
            "total": total,
            "stored": c["filled"],
            "inserted": c["inserted"],
            "merged": c["merged"],
            "dropped": c["dropped"] + c["guard"],
            "overflow": c["merged"] + c["dropped"],
            "guard_abandoned": c["guard"],
            "max_per_pixel_over_k": c["max_count"],
        }
        frame.stats["geometry_passes"] = 1
        over = c["merged"] + c["dropped"]
        if over:
            how = "merged into the farthest slot" if self.settings["overflow"] == "merge" else "dropped"
            frame.stats.warn(
                f"k-buffer overflow: {over} fragments beyond k={self.k} {how} (deepest pixel had "
                f"{c['max_count']} fragments); raise transparency.k for an exact result"
            )
        if c["guard"]:
            frame.stats.warn(
                f"k-buffer: {c['guard']} fragments hit max_spins waiting for a pixel lock and were dropped"
            )
        return False

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """Locked sorted insertion."""
        return "approx/kbuffer_insert.glsl.j2"

    def resolve_template(self) -> str:
        """Sorted slot walk."""
        return "approx/kbuffer_resolve.glsl.j2"

    def template_vars(self) -> dict:
        """k, overflow policy and spin bound (compile-time constants)."""
        return {
            "k": self.k,
            "overflow": self.settings["overflow"],
            "max_spins": int(self.settings["max_spins"]),
            "kb_lock": self.lock,
            "fragment_interlock": self.lock == "interlock",
        }

    def extensions(self) -> str:
        """Fragment shader interlock where it is the critical section."""
        return "#extension GL_ARB_fragment_shader_interlock : require\n" if self.lock == "interlock" else ""

    def bind_composite(self, frame, program) -> None:
        """The composite reads the same slots."""
        self._bind()

    def memory(self) -> dict:
        """Heads, slots (allocated and filled) and counters, in bytes."""
        if self._heads is None:
            return {}
        heads = self._pixels * HEAD_BYTES
        return {
            "kbuffer_heads": heads,
            "kbuffer_heads_used": heads,
            "kbuffer_slots": self._pixels * self.k * SLOT_BYTES,
            "kbuffer_slots_used": self._filled * SLOT_BYTES,
            "kbuffer_node_bytes": SLOT_BYTES,
        }

    def release(self) -> None:
        """Free all buffers."""
        for b in (self._heads, self._slots, self._counters):
            if b is not None:
                b.release()
        self._heads = self._slots = self._counters = None


register("method")(
    MethodSpec(
        "kbuffer",
        "k nearest fragments per pixel in fixed sorted slots; overflow merged or dropped",
        KBuffer,
        settings={
            "k": Setting((int,), 8, "fragment slots per pixel (1..64)", check=_k),
            "overflow": Setting(
                (str,), "merge", "fragments beyond k: merge into the farthest slot, or drop", choices=("merge", "drop")
            ),
            "max_spins": Setting(
                (int,),
                65536,
                "bound on lock attempts per fragment (a fragment that never wins the lock is dropped and counted)",
                check=lambda v: None if v > 0 else "must be > 0",
            ),
            "lock": LOCK_SETTING,
        },
    )
)
