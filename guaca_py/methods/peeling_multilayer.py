"""Multi-layer depth peeling via fragment sort (Liu et al. 2009): the M nearest remaining layers per pass.

Each pass keeps, per pixel, the M nearest fragments above the pixel's lower bound in M slots
(sorted by (depth, tie)); a compute step shades them front to back and moves the bound past the
last one; passes repeat until a pass leaves nothing unpeeled. The original resolves write races
of its MRT read-modify-write by repeating passes until nothing changes; here the slots are
updated with atomics instead, so one pass per M layers suffices. Without 64-bit atomics a
(depth, tie) key cannot be swapped atomically, so slots hold 32-bit handles of immutable nodes in
a pool and insertion is a chain of compare-and-swaps (peeling/multilayer_insert.glsl.j2). Needs
no ordering extension.

The pool is the only storage that can run out. Where it drops a fragment, the step shades only
slots in front of the nearest dropped depth (exact); the rest is peeled again next pass. With
pool_mb 'auto' the pool then grows to the pass's need, so the next pass cannot overflow.
"""

from __future__ import annotations

from ..limits import require_bytes
from ..pipeline.settings import Setting, auto_or_positive_mb, positive
from ..registry import register
from ..shaders.slots import Buffer
from .base import MethodSpec
from .peeling import PEEL_SETTINGS, Peeling, PeelKind
from .shared_pool import ViewsNeed

NODE_BYTES = 32  # 8 payload words
INF_BITS = 0x7F800000  # +inf: "nothing dropped" in the per-pixel dropped-depth words


def _layers(v) -> str | None:
    return None if 1 <= v <= 32 else f"must be in 1..32, got {v}"


class NodePool:
    """Multi-layer peeling's storage beside the peeling textures: M slots per pixel, the node pool
    they point into and each pixel's nearest dropped depth."""

    def __init__(self, method: Peeling):
        self.method = method
        self.caps, self.settings = method.caps, method.settings
        self.layers = int(self.settings["layers_per_pass"])
        self.capacity = 0
        self._slots = self._nodes = self._dropped = None
        self._pixels = 0
        self.used_nodes = 0  # most nodes one pass of this frame used
        self._held = 0  # what the last call's largest view used: the next call's first frame may shrink to it
        self._views_need = ViewsNeed()  # the views of one render_views() call share the pool

    def step_vars(self) -> dict:
        """M is compiled into the insertion and the step."""
        return {"ml_layers": self.layers}

    def pool_nodes(self, mb: float) -> int:
        """Nodes in `mb` megabytes, within the device's storage rule (guaca_py/limits.py)."""
        cap = self.caps.limits.elements(NODE_BYTES) if self.caps.limits else 2**31 // NODE_BYTES
        return max(2, min(int(mb * 1024 * 1024) // NODE_BYTES, cap, 2**32 - 1))

    def alloc(self, frame, capacity: int) -> None:
        """Per-pixel slots and dropped depths for the frame size, and a pool of `capacity` nodes."""
        ctx = frame.ctx
        pixels = frame.pixel_count
        if self._slots is None or self._pixels != pixels:
            for b in (self._slots, self._dropped):
                if b is not None:
                    b.release()
            require_bytes(
                self.caps.limits,
                pixels * self.layers * 4,
                "transparency.layers_per_pass",
                f"lower layers_per_pass (now {self.layers}) or the resolution",
            )
            self._pixels = pixels
            self._slots = ctx.buffer(reserve=pixels * self.layers * 4)
            self._slots.clear()
            self._dropped = ctx.buffer(data=bytes(memoryview((INF_BITS).to_bytes(4, "little") * pixels)))
        if self._nodes is None or self.capacity != capacity:
            if self._nodes is not None:
                self._nodes.release()
            self.capacity = capacity
            self._nodes = ctx.buffer(reserve=capacity * NODE_BYTES)

    def prepare(self, frame) -> None:
        """Per-pixel state and the node pool (one node per pixel and layer to start with)."""
        pool = self.settings["pool_mb"]
        if pool == "auto":
            start = min(max(1024, frame.pixel_count * self.layers + 1), self.pool_nodes(self.settings["max_pool_mb"]))
            cap = self.capacity if self._pixels == frame.pixel_count and self.capacity else start
            held, self._held = self._held, 0
            if held and held + 1 < cap // 4:
                # the last frame (with several views: its largest view) used under a quarter: hold
                # what the scene needs (a deeper frame grows the pool again between its passes,
                # no frame is lost)
                cap = max(1024, int(held * 1.15) + 2)
        else:
            cap = self.pool_nodes(pool)
        self.alloc(frame, cap)
        self.used_nodes = 0

    def frame_done(self, frame) -> None:
        """After a frame's passes: at a call's last view, what its largest view used (methods/shared_pool.py)."""
        largest = self._views_need(frame, self.used_nodes)
        if largest is not None:
            self._held = largest

    def bind(self) -> None:
        """Slots, pool and dropped depths on the storage bindings the insertion and the steps read."""
        self._slots.bind_to_storage_buffer(Buffer.MULTILAYER_SLOTS)
        self._nodes.bind_to_storage_buffer(Buffer.MULTILAYER_NODES)
        self._dropped.bind_to_storage_buffer(Buffer.MULTILAYER_DROPPED)

    def memory(self) -> dict:
        """Slots, node pool (allocated and most used in one pass) and dropped depths, in bytes."""
        if self._slots is None:
            return {}
        return {
            "peel_ml_slots": self._slots.size,
            "peel_ml_slots_used": self._slots.size,
            "peel_ml_dropped": self._dropped.size,
            "peel_ml_dropped_used": self._dropped.size,
            "peel_ml_pool": self.capacity * NODE_BYTES,
            "peel_ml_pool_used": (self.used_nodes + 1) * NODE_BYTES,
        }

    def release(self) -> None:
        """Free the pool and per-pixel buffers."""
        for b in (self._slots, self._nodes, self._dropped):
            if b is not None:
                b.release()
        self._slots = self._nodes = self._dropped = None
        self._pixels = 0
        self.capacity = 0


def peel_multilayer(m: Peeling, frame) -> None:
    """Passes of M layers until one leaves nothing unpeeled (or the cap / a full fixed pool stops it)."""
    pool: NodePool = m.storage
    s = m.stats
    s.update(pool_overflow=0, pool_grown=0, rejected=0, guard_abandoned=0)
    left = stalled = 0
    max_nodes = pool.pool_nodes(m.settings["max_pool_mb"])
    while True:
        if m.cap_reached():
            m.truncate(left)
            break
        m.reset_counters(alloc=1)  # node 0 is the null handle
        pool.bind()
        # a pool that can no longer grow cuts each pass at the nearest depth it dropped there
        can_grow = m.settings["pool_mb"] == "auto" and pool.capacity < max_nodes
        m.geometry_pass(
            frame,
            "multilayer",
            uniforms={
                "gua_ml_capacity": pool.capacity,
                "gua_ml_max_steps": int(m.settings["max_steps"]),
                "gua_ml_cut": not can_grow,
            },
        )
        m.step(frame, "multilayer")
        c = m.read_counters()
        s["iterations"] += 1
        s["peeled"] += c["peeled"]
        s["saturated_pixels"] += c["saturated"]
        s["pool_overflow"] += c["overflow"]
        s["rejected"] += c["rejected"]
        s["guard_abandoned"] += c["guard"]
        requested = c["alloc"] - 1
        pool.used_nodes = max(pool.used_nodes, min(requested, pool.capacity - 1))
        left = c["in_range"] - c["peeled"]
        if left == 0:
            break
        stalled = stalled + 1 if c["peeled"] == 0 else 0
        if c["overflow"] and can_grow:
            # Grow so that the next pass cannot overflow: it allocates at most one node per fragment it sees.
            want = max(requested, c["in_range"]) + 2
            pool.alloc(frame, min(max_nodes, int(want * 1.1)))
            s["pool_grown"] += 1
        elif stalled >= 3:
            # three passes without a peeled fragment: stop (counted) rather than loop for ever
            s["truncated"] = left
            why = (
                f"the node pool ({pool.capacity - 1} nodes) is too small to make progress "
                "(raise transparency.pool_mb or use 'auto')"
                if c["overflow"]
                else f"every insertion hit max_steps ({m.settings['max_steps']}; raise it)"
            )
            m.warn(f"{m.id}: {why}; {left} fragments not peeled")
            break
    pool.frame_done(frame)
    if s["pool_overflow"] and m.settings["pool_mb"] != "auto":
        m.warn(
            f"{m.id}: node pool overflowed ({s['pool_overflow']} nodes lacking, "
            f"{pool.capacity - 1} nodes); those layers were peeled in later passes"
        )
    if s["guard_abandoned"]:
        m.warn(f"{m.id}: {s['guard_abandoned']} insertions hit max_steps; peeled again in later passes")


register("method")(
    MethodSpec(
        "multilayer_depth_peeling",
        "multi-layer depth peeling via fragment sort: M nearest layers per pass (atomic slot chain)",
        Peeling,
        # no ordered per-pixel state: the slots live in a buffer updated with atomics
        PeelKind("multilayer", peel_multilayer, needs_ordering=False, storage=NodePool),
        {
            **PEEL_SETTINGS,
            "layers_per_pass": Setting((int,), 4, "M: layers kept per pixel and pass", check=_layers),
            "pool_mb": Setting(
                (str, int, float),
                "auto",
                "node pool in MB, or 'auto' (grows to a pass's need)",
                check=auto_or_positive_mb,
            ),
            "max_pool_mb": Setting((int, float), 512, "largest pool 'auto' may grow to", check=positive),
            "max_steps": Setting(
                (int,), 1024, "bound on swap attempts per insertion (guards against livelock)", check=positive
            ),
        },
        geometry_passes=None,
        geometry_passes_rule="layers/M",
    )
)
