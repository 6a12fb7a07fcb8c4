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
from ..pipeline.settings import Setting, positive
from ..shaders.slots import Buffer
from .peeling import PeelingMethod

NODE_BYTES = 32  # 8 payload words
INF_BITS = 0x7F800000  # +inf: "nothing dropped" in the per-pixel dropped-depth words


def _pool(v) -> str | None:
    if v == "auto" or (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
        return None
    return f"must be 'auto' or a positive number of MB, got {v!r}"


def _layers(v) -> str | None:
    return None if 1 <= v <= 32 else f"must be in 1..32, got {v}"


class MultiLayerDepthPeeling(PeelingMethod):
    """M layers per geometry pass from an atomic per-pixel fragment sort; repeats until nothing is left."""

    id = "multilayer_depth_peeling"
    geometry_passes = "layers/M"
    summary = "multi-layer depth peeling via fragment sort: M nearest layers per pass (atomic slot chain)"
    step_method = "multilayer"
    needs_ordering = False
    SETTINGS = {
        **PeelingMethod.SETTINGS,
        "layers_per_pass": Setting((int,), 4, "M: layers kept per pixel and pass", check=_layers),
        "pool_mb": Setting(
            (str, int, float), "auto", "node pool in MB, or 'auto' (grows to a pass's need)", check=_pool
        ),
        "max_pool_mb": Setting((int, float), 512, "largest pool 'auto' may grow to", check=positive),
        "max_steps": Setting(
            (int,), 1024, "bound on swap attempts per insertion (guards against livelock)", check=positive
        ),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self.layers = int(settings["layers_per_pass"])
        self.capacity = 0
        self._slots = self._nodes = self._dropped = None
        self._pixels = 0
        self._used_nodes = 0

    def step_vars(self) -> dict:
        """M is compiled into the insertion and the step."""
        return {"ml_layers": self.layers}

    def phase_slots(self, phase):
        """No ordered per-pixel state: the slots live in a buffer updated with atomics."""
        return []

    # ------------------------------------------------------------------ storage
    def _pool_nodes(self, mb: float) -> int:
        """Nodes in `mb` megabytes, within the device's storage rule (guaca_py/limits.py)."""
        cap = self.caps.limits.elements(NODE_BYTES) if self.caps.limits else 2**31 // NODE_BYTES
        return max(2, min(int(mb * 1024 * 1024) // NODE_BYTES, cap, 2**32 - 1))

    def _alloc_pool(self, frame, capacity: int) -> None:
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
            start = min(max(1024, frame.pixel_count * self.layers + 1), self._pool_nodes(self.settings["max_pool_mb"]))
            cap = self.capacity if self._pixels == frame.pixel_count and self.capacity else start
            if self._used_nodes and self._used_nodes + 1 < cap // 4:
                # the last frame used under a quarter: hold what the scene needs (a deeper frame
                # grows the pool again between its passes, no frame is lost)
                cap = max(1024, int(self._used_nodes * 1.15) + 2)
        else:
            cap = self._pool_nodes(pool)
        self._alloc_pool(frame, cap)
        self._used_nodes = 0
        super().prepare(frame)

    def _bind_step_storage(self, frame) -> None:
        self._slots.bind_to_storage_buffer(Buffer.MULTILAYER_SLOTS)
        self._nodes.bind_to_storage_buffer(Buffer.MULTILAYER_NODES)
        self._dropped.bind_to_storage_buffer(Buffer.MULTILAYER_DROPPED)

    # ------------------------------------------------------------------ passes
    def render_transparent(self, frame) -> None:
        """Passes of M layers until one leaves nothing unpeeled (or the cap / a full fixed pool stops it)."""
        s = self._stats
        s.update(pool_overflow=0, pool_grown=0, rejected=0, guard_abandoned=0)
        left = stalled = 0
        max_nodes = self._pool_nodes(self.settings["max_pool_mb"])
        while True:
            if self.cap_reached():
                self._truncate(left)
                break
            self.reset_counters(alloc=1)  # node 0 is the null handle
            self._bind_step_storage(frame)
            # a pool that can no longer grow cuts each pass at the nearest depth it dropped there
            can_grow = self.settings["pool_mb"] == "auto" and self.capacity < max_nodes
            self.geometry_pass(
                frame,
                "multilayer",
                [],
                uniforms={
                    "gua_ml_capacity": self.capacity,
                    "gua_ml_max_steps": int(self.settings["max_steps"]),
                    "gua_ml_cut": not can_grow,
                },
            )
            self.step(frame, "multilayer")
            c = self.read_counters()
            s["iterations"] += 1
            s["peeled"] += c["peeled"]
            s["saturated_pixels"] += c["saturated"]
            s["pool_overflow"] += c["overflow"]
            s["rejected"] += c["rejected"]
            s["guard_abandoned"] += c["guard"]
            requested = c["alloc"] - 1
            self._used_nodes = max(self._used_nodes, min(requested, self.capacity - 1))
            left = c["in_range"] - c["peeled"]
            if left == 0:
                break
            stalled = stalled + 1 if c["peeled"] == 0 else 0
            if c["overflow"] and can_grow:
                # Grow so that the next pass cannot overflow: it allocates at most one node per fragment it sees.
                want = max(requested, c["in_range"]) + 2
                self._alloc_pool(frame, min(max_nodes, int(want * 1.1)))
                s["pool_grown"] += 1
            elif stalled >= 3:
                # three passes without a peeled fragment: stop (counted) rather than loop for ever
                s["truncated"] = left
                why = (
                    f"the node pool ({self.capacity - 1} nodes) is too small to make progress "
                    "(raise transparency.pool_mb or use 'auto')"
                    if c["overflow"]
                    else f"every insertion hit max_steps ({self.settings['max_steps']}; raise it)"
                )
                self.warn(f"{self.id}: {why}; {left} fragments not peeled")
                break
        if s["pool_overflow"] and self.settings["pool_mb"] != "auto":
            self.warn(
                f"{self.id}: node pool overflowed ({s['pool_overflow']} nodes lacking, "
                f"{self.capacity - 1} nodes); those layers were peeled in later passes"
            )
        if s["guard_abandoned"]:
            self.warn(f"{self.id}: {s['guard_abandoned']} insertions hit max_steps; peeled again in later passes")

    def memory(self) -> dict:
        """Per-pixel textures plus slots, node pool (allocated and most used in one pass) and dropped depths."""
        out = super().memory()
        if self._slots is not None:
            out["peel_ml_slots"] = out["peel_ml_slots_used"] = self._slots.size
            out["peel_ml_dropped"] = out["peel_ml_dropped_used"] = self._dropped.size
            out["peel_ml_pool"] = self.capacity * NODE_BYTES
            out["peel_ml_pool_used"] = (self._used_nodes + 1) * NODE_BYTES
        return out

    def release(self) -> None:
        """Free the pool and per-pixel buffers too."""
        super().release()
        for b in (self._slots, self._nodes, self._dropped):
            if b is not None:
                b.release()
        self._slots = self._nodes = self._dropped = None
        self._pixels = 0
        self.capacity = 0
