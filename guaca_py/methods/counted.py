"""Counted storage: Dynamic Fragment Buffer, S-buffer (two geometry passes) and paged linked lists.

dfb and sbuffer count the fragments of each pixel in a first geometry pass, turn the counts into
per-pixel ranges of one fragment array sized exactly to the frame's total (read back as one
word), and store the shaded-later payload of every fragment in a second pass. paged_ll stores
into pages of P fragments linked per pixel in a single pass and grows its page pool on overflow.
All three resolve by sorting each pixel's fragments by (depth, tie id) in the composite pass, and
share one class: the storage layout (`dfb`, `sbuffer` or `paged`) is each method's option.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from ..gpu_counters import CounterBlock, StagedReader
from ..growth import idles, with_margin
from ..pipeline.settings import Setting, auto_or_positive_mb, non_negative, positive
from ..prefix_sum import GpuFill, PrefixSum, dispatch_grid
from ..registry import register
from ..shaders import set_uniform
from ..shaders.slots import Buffer
from .base import MethodSpec, TransparencyMethod
from .shared_pool import ViewsNeed

PAYLOAD_BYTES = 32  # common/payload_pack.glsl.j2: 8 words per fragment
COUNTERS = ("stored", "overflow", "alloc", "wasted_pages", "guard")


def _chunk(v) -> str | None:
    return None if 1 <= v <= 256 else f"must be in 1..256, got {v}"


def _counters_check(v) -> str | None:
    return None if 1 <= v <= 65536 else f"must be in 1..65536, got {v}"


def _page_check(v) -> str | None:
    return None if 1 <= v <= 64 else f"must be in 1..64, got {v}"


_PHASE_TEMPLATES = {
    "count": "counted/count.glsl.j2",
    "store": "counted/store.glsl.j2",
    "insert": "counted/paged_insert.glsl.j2",
}
# storage binding -> buffer name, per layout (counted/*.glsl.j2)
_BINDINGS = {
    "dfb": {
        Buffer.COUNTED_PIXELS: "pixels",
        Buffer.COUNTED_NODES: "nodes",
        Buffer.COUNTED_COUNTS: "counts",
        Buffer.COUNTED_COUNTERS: "counters",
    },
    "sbuffer": {
        Buffer.COUNTED_PIXELS: "pixels",
        Buffer.COUNTED_NODES: "nodes",
        Buffer.COUNTED_COUNTS: "counts",
        Buffer.COUNTED_COUNTERS: "counters",
        Buffer.COUNTED_GROUP_BASE: "group_base",
    },
    "paged": {
        Buffer.COUNTED_PIXELS: "pixels",
        Buffer.COUNTED_NODES: "nodes",
        Buffer.COUNTED_LINKS: "links",
        Buffer.COUNTED_COUNTERS: "counters",
    },
}


@dataclass(frozen=True)
class CountedKind:
    """Where a counted-storage method puts each pixel's fragments."""

    layout: str  # "dfb" (counted, scanned over all pixels), "sbuffer" (counted, S shared counters) or "paged"


class CountedStorage(TransparencyMethod):
    """Per-pixel fragment storage sized from counts (dfb, sbuffer) or grown in pages (paged_ll), sorted at resolve."""

    antialiasing_refusal = "its counted records carry no coverage mask (counting and storing passes are per pixel)"

    def __init__(self, spec, settings, caps):
        super().__init__(spec, settings, caps)
        self.layout = spec.options.layout
        self.paged = self.layout == "paged"
        self.phase = "resolve"
        self._pixels = 0
        self._bufs: dict = {}
        self._scan = self._fill = None
        self._counters: CounterBlock | None = None
        self._reader: StagedReader | None = None
        self._last: dict = {}
        if self.paged:
            self.page = int(settings["page_size"])
            self.fill_bits = max(1, self.page.bit_length())  # holds 0..P
            self.page_bytes = self.page * PAYLOAD_BYTES + 4  # payload slots + link
            self.capacity = 0  # pages in the pool, null page 0 included
            self._want = 0  # pool size requested for the next prepare()
            self._views_need = ViewsNeed()  # the views of one render_views() call share the pool

    # ------------------------------------------------------------------ helpers
    def _tools(self, frame) -> None:
        if self._scan is None:
            self._scan = PrefixSum(frame.ctx, frame.programs)
            self._fill = GpuFill(frame.programs)
            self._reader = StagedReader(frame.ctx)

    def _buffer(self, ctx, name: str, nbytes: int):
        """A buffer of exactly `nbytes` (at least 4), re-specified only when the size changes."""
        nbytes = max(int(nbytes), 4)
        buf = self._bufs.get(name)
        if buf is None:
            buf = self._bufs[name] = ctx.buffer(reserve=nbytes)
        elif buf.size != nbytes:
            buf.orphan(nbytes)
        return buf

    def _max_slots(self, ctx, slot_bytes: int) -> int:
        """Storage cap in slots: budget_mb if set, and the device's storage rule (guaca_py/limits.py)."""
        limit = self.caps.limits.max_buffer_bytes if self.caps.limits else 2**31 - 1
        if self.settings["budget_mb"] != "auto":
            limit = min(limit, int(self.settings["budget_mb"] * 1024 * 1024))
        return max(1, min(limit // slot_bytes, 2**32 - 1))

    def _cap_reason(self) -> str:
        """Which limit capped the storage, and what to do about it."""
        device = self.caps.limits.max_buffer_bytes if self.caps.limits else 2**31 - 1
        if self.settings["budget_mb"] != "auto" and self.settings["budget_mb"] * 1024 * 1024 < device:
            return "transparency.budget_mb; raise it or use 'auto'"
        where = self.caps.limits.describe() if self.caps.limits else "2 GiB per buffer"
        return f"the device's limit, {where}; render fewer layers or pixels"

    def _reset_counters(self, ctx, alloc_start: int = 0) -> None:
        if self._counters is None:
            self._counters = CounterBlock(ctx, COUNTERS)
        self._counters.reset(alloc=alloc_start)

    def _state_begin(self, frame) -> None:
        """Transparent draws test against the opaque depth without writing it."""
        mgl = moderngl
        g = frame.resources["gbuffer"]
        g.depth_only.use()
        g.depth_only.depth_mask = False
        frame.ctx.enable(mgl.DEPTH_TEST)
        frame.ctx.depth_func = "<"

    def _draw(self, frame, phase: str, uniforms: dict) -> None:
        self.phase = phase
        self._bind()
        frame.draw_transparent(uniforms)
        frame.ctx.memory_barrier()

    def _bind(self) -> None:
        for binding, name in _BINDINGS[self.layout].items():
            if name == "counters":
                self._counters.bind(binding)
            else:
                self._bufs[name].bind_to_storage_buffer(binding)

    def _warn(self, frame, text: str) -> None:
        frame.stats.warn(text)

    # ------------------------------------------------------------------ frame
    def prepare(self, frame) -> None:
        """Size the storage and zero what the geometry passes count into."""
        self._tools(frame)
        if self.paged:
            self._prepare_pages(frame)
        else:
            self._prepare_arrays(frame)

    def render_transparent(self, frame) -> None:
        """Count, address and store (dfb, sbuffer), or append to the pages (paged_ll)."""
        self._state_begin(frame)
        if self.paged:
            self._draw(frame, "insert", {"gua_cs_capacity": self.capacity})
        else:
            self._count_and_store(frame)
        self.phase = "resolve"
        frame.resources["gbuffer"].fbo.depth_mask = True

    def finish(self, frame) -> bool:
        """Read the counters into frame.stats; paged_ll may grow its pool and ask for a re-render."""
        return self._finish_pages(frame) if self.paged else self._finish_arrays(frame)

    def memory(self) -> dict:
        """Bytes of the storage, allocated and used."""
        if not self._bufs:
            return {}
        return self._page_memory() if self.paged else self._array_memory()

    # ------------------------------------------------------------------ dfb, sbuffer
    def _prepare_arrays(self, frame) -> None:
        """Size per-pixel buffers, zero the counts and counters."""
        ctx, n = frame.ctx, frame.pixel_count
        self._pixels = n
        if self.layout == "sbuffer":
            s = int(self.settings["counters"])
            self._buffer(ctx, "pixels", n * 8)
            self._buffer(ctx, "groups", s * 4)
            self._buffer(ctx, "group_base", (s + 1) * 4)
        else:
            self._buffer(ctx, "pixels", (n + 1) * 4)
        self._buffer(ctx, "counts", n * 4)
        if "nodes" not in self._bufs:
            self._buffer(ctx, "nodes", PAYLOAD_BYTES)  # sized to the frame's total before the store pass
        self._fill.run(self._bufs["counts"], n, 0)
        self._reset_counters(ctx)
        ctx.memory_barrier()

    def _addresses(self, frame) -> int:
        """Per-pixel offsets from the counts; returns the frame's fragment total (one word read back).

        dfb scans the counts of all pixels; the S-buffer reserves each pixel's range from one of S
        counters (pixel p mod S) and scans only the S totals.
        """
        n = frame.pixel_count
        if self.layout == "dfb":
            self._scan.run(self._bufs["counts"], self._bufs["pixels"], n)
            return int(np.frombuffer(self._reader.read(self._bufs["pixels"], 4, n * 4), dtype=np.uint32)[0])
        s = int(self.settings["counters"])
        self._fill.run(self._bufs["groups"], s, 0)
        frame.ctx.memory_barrier()
        prog = frame.programs.compute("counted/sbuffer_address.comp.j2", counters=s)
        self._bufs["pixels"].bind_to_storage_buffer(Buffer.COUNTED_PIXELS)
        self._bufs["counts"].bind_to_storage_buffer(Buffer.COUNTED_COUNTS)
        self._bufs["groups"].bind_to_storage_buffer(Buffer.COUNTED_GROUPS)
        prog["gua_pixel_count"] = n
        prog.run(*dispatch_grid(math.ceil(n / 256)))
        frame.ctx.memory_barrier()
        self._scan.run(self._bufs["groups"], self._bufs["group_base"], s)
        return int(np.frombuffer(self._reader.read(self._bufs["group_base"], 4, s * 4), dtype=np.uint32)[0])

    def _count_and_store(self, frame) -> None:
        """Count pass, addressing, exact allocation, store pass."""
        self._draw(frame, "count", {})
        total = self._addresses(frame)
        capacity = min(total, self._max_slots(frame.ctx, PAYLOAD_BYTES))
        self._buffer(frame.ctx, "nodes", capacity * PAYLOAD_BYTES)
        self._last = {"total": total, "capacity": capacity}
        if total:
            self._draw(frame, "store", {"gua_cs_capacity": capacity})

    def _finish_arrays(self, frame) -> bool:
        """Counters into frame.stats (exact allocation: never asks for a re-render)."""
        c = self._counters.read()
        total, capacity = self._last["total"], self._last["capacity"]
        frame.stats["geometry_passes"] = 2
        frame.stats["fragments"] = {
            "stored": c["stored"],
            "counted": total,
            "overflow": c["overflow"],
            "dropped": c["overflow"],
            "unfilled": max(0, min(total, capacity) - c["stored"]),
            "early_termination_culled": 0,
        }
        if capacity < total:
            self._warn(
                frame,
                f"{self.id}: frame needs {total} fragments, storage capped at {capacity} "
                f"by {self._cap_reason()}; {c['overflow']} dropped",
            )
        elif c["overflow"] or c["stored"] != total:
            self._warn(
                frame,
                f"{self.id}: store pass saw {c['stored'] + c['overflow']} fragments, count pass "
                f"{total}; {c['overflow']} dropped (rasterization differed between passes)",
            )
        self._last["stored"] = c["stored"]
        return False

    def _array_memory(self) -> dict:
        """Per-pixel counts and offsets, fragment array (allocated == the frame's need), scan buffers; S-buffer groups."""
        out = {
            "counted_counts": self._bufs["counts"].size,
            "counted_offsets": self._bufs["pixels"].size,
            "counted_fragments": self._bufs["nodes"].size,
            "counted_fragments_used": self._last.get("stored", 0) * PAYLOAD_BYTES,
            "counted_scan_aux": self._scan.aux_bytes() if self._scan else 0,
            "counted_node_bytes": PAYLOAD_BYTES,
        }
        if self.layout == "sbuffer":
            out["counted_groups"] = self._bufs["groups"].size + self._bufs["group_base"].size
        return out

    # ------------------------------------------------------------------ paged_ll
    def _page_limit(self, ctx) -> int:
        """Most pages: storage cap, and page indices must fit the head word next to the fill."""
        return min(self._max_slots(ctx, self.page * PAYLOAD_BYTES), 2 ** (32 - self.fill_bits) - 1)

    def _paged_hint(self, limit: int, auto: bool) -> str:
        """What bounded the page pool, and what to do about it."""
        if self.capacity < limit:
            return "raise transparency.budget_mb or use 'auto'" if not auto else "raise transparency.max_regrow"
        if limit == 2 ** (32 - self.fill_bits) - 1 and self.page > 1:
            return f"page indices are {32 - self.fill_bits} bits beside the fill count: try a smaller page_size"
        return f"capped by {self._cap_reason()}"

    def _prepare_pages(self, frame) -> None:
        """Size the page pool (requested size, previous size or a first guess), clear heads and counters."""
        ctx, n = frame.ctx, frame.pixel_count
        if self._want:
            cap, self._want = self._want, 0
        elif self._pixels == n and self.capacity:
            cap = self.capacity
        elif self.settings["budget_mb"] != "auto":
            cap = self._page_limit(ctx)
        else:
            cap = max(1024, math.ceil(n / self.page))  # room for P layers per pixel; grown on overflow
        self.capacity = max(2, min(cap, self._page_limit(ctx)))
        self._pixels = n
        self._buffer(ctx, "pixels", n * 4)
        self._buffer(ctx, "nodes", self.capacity * self.page * PAYLOAD_BYTES)
        self._buffer(ctx, "links", self.capacity * 4)
        self._fill.run(self._bufs["pixels"], n, 0)
        self._reset_counters(ctx, alloc_start=1)  # page 0 is the null page
        ctx.memory_barrier()

    def _finish_pages(self, frame) -> bool:
        """Counters into frame.stats; with an 'auto' budget grow the pool after overflow and ask for a re-render."""
        c = self._counters.read()
        requested = c["alloc"] - 1
        used = min(requested, self.capacity - 1)
        frame.stats["geometry_passes"] = 1
        frame.stats["fragments"] = {
            "stored": c["stored"],
            "overflow": c["overflow"],
            "dropped": c["overflow"] + c["guard"],
            "guard_abandoned": c["guard"],
            "pages_used": used,
            "pages_requested": requested,
            "pages_wasted": c["wasted_pages"],
            "early_termination_culled": 0,
        }
        self._last = {"used_pages": used, "stored": c["stored"]}
        # Pages lost to races (allocated, not published) vary from frame to frame on a GPU: the pool
        # keeps this frame's loss once more as margin, so a later frame that loses more (the same
        # scene, another call) fits instead of growing the pool again (seen on the H100: a steady
        # two-view scene regrew in its third call).
        margin = c["wasted_pages"]
        largest = self._views_need(frame, used + margin)  # of this call's views, known at its last
        auto = self.settings["budget_mb"] == "auto"
        limit = self._page_limit(frame.ctx)
        regrown = frame.stats.get("regrown", 0)  # re-renders of this frame so far
        if c["overflow"] and auto and regrown < self.settings["max_regrow"] and self.capacity < limit:
            # Every dropped fragment asked for at most one page, so `requested` bounds the need
            # from above (by up to P times: measured 5.2M pages asked, 1.18M needed); fragments of
            # one pixel share pages, so used + overflow / P bounds it from below. Grow to the lower
            # bound and take the upper one on the last re-render max_regrow allows.
            last = regrown + 1 >= self.settings["max_regrow"]
            need = (requested if last else used + math.ceil(c["overflow"] / self.page)) + margin
            self._want = min(limit, with_margin(need))
            self._warn(
                frame,
                f"paged_ll: pool of {self.capacity - 1} pages overflowed by {c['overflow']} "
                f"fragments; grown to {self._want - 1} pages and re-rendered",
            )
            return True
        if c["overflow"]:
            hint = self._paged_hint(limit, auto)
            self._warn(
                frame,
                f"paged_ll overflow: {c['overflow']} fragments dropped (pool {self.capacity - 1} "
                f"pages of {self.page}); {hint}",
            )
        if c["guard"]:
            self._warn(frame, f"{c['guard']} paged_ll insertions hit max_steps and were dropped")
        if auto and largest is not None and not c["overflow"] and idles(self.capacity, largest):
            # shrink for the next frame (this frame still reads the current pool; growth.py); with
            # several views, to what the largest of them used (methods/shared_pool.py)
            self._want = with_margin(largest)
        return False

    def _page_memory(self) -> dict:
        """Heads, page pool (allocated and used, links included) and the bytes of stored payload."""
        used = self._last.get("used_pages", 0)
        return {
            "counted_heads": self._pixels * 4,
            "counted_pages": self.capacity * self.page_bytes,
            "counted_pages_used": (used + 1) * self.page_bytes,
            "counted_fragments_used": self._last.get("stored", 0) * PAYLOAD_BYTES,
            "counted_node_bytes": PAYLOAD_BYTES,
        }

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """The current geometry phase's code (count, store or paged insert)."""
        return _PHASE_TEMPLATES.get(self.phase, _PHASE_TEMPLATES["insert" if self.paged else "count"])

    def template_vars(self) -> dict:
        """Storage layout, the current phase (count/store/insert/resolve), the sort chunk and the layout's own."""
        v = {"cs_layout": self.layout, "phase": self.phase, "sort_chunk": int(self.settings["sort_chunk"])}
        if self.layout == "sbuffer":
            v["counters"] = int(self.settings["counters"])
        elif self.paged:
            v.update(page_size=self.page, fill_bits=self.fill_bits, max_steps=int(self.settings["max_steps"]))
        return v

    def resolve_template(self) -> str:
        """Chunked sort + front-to-back blend of each pixel's fragments."""
        return "counted/resolve.glsl.j2"

    def bind_composite(self, frame, program) -> None:
        """The composite reads the same storage."""
        self.phase = "resolve"
        self._bind()
        capacity = self.capacity if self.paged else self._last.get("capacity", 0)
        set_uniform(program, "gua_cs_capacity", capacity)

    def composite_threshold(self) -> float:
        """Exact: the walk only stops at full opacity."""
        return 1.0

    def release(self) -> None:
        """Free all buffers."""
        for b in self._bufs.values():
            b.release()
        self._bufs = {}
        for obj in (self._scan, self._counters, self._reader):
            if obj is not None:
                obj.release()
        self._scan = self._counters = self._reader = None
        self._pixels = 0


_STORAGE_SETTINGS = {
    "budget_mb": Setting(
        (str, int, float),
        "auto",
        "cap on fragment storage in MB, or 'auto' (the frame's need)",
        check=auto_or_positive_mb,
    ),
    "sort_chunk": Setting((int,), 32, "fragments sorted per resolve sweep (local array size)", check=_chunk),
}

for _spec in (
    MethodSpec(
        "dfb",
        "dynamic fragment buffer: count, prefix sum, exact per-pixel arrays, sort at resolve",
        CountedStorage,
        CountedKind("dfb"),
        _STORAGE_SETTINGS,
        geometry_passes=2,
    ),
    MethodSpec(
        "sbuffer",
        "S-buffer: count, S shared counters + scan of the counters, exact arrays, sort at resolve",
        CountedStorage,
        CountedKind("sbuffer"),
        {
            **_STORAGE_SETTINGS,
            # Vasilakis & Fudos report about 30 counters as the sweet spot (survey §3.4).
            "counters": Setting((int,), 32, "S: address counters shared by pixel p mod S", check=_counters_check),
        },
        geometry_passes=2,
    ),
    MethodSpec(
        "paged_ll",
        "paged per-pixel linked lists (P fragments per page), lock-free, sort at resolve",
        CountedStorage,
        CountedKind("paged"),
        {
            **_STORAGE_SETTINGS,
            "page_size": Setting((int,), 4, "P: fragments per page", check=_page_check),
            "max_regrow": Setting(
                (int,), 2, "re-renders allowed to grow an 'auto' pool after overflow", check=non_negative
            ),
            "max_steps": Setting(
                (int,), 4096, "bound on retries per insertion (guards against livelock)", check=positive
            ),
        },
    ),
):
    register("method")(_spec)
