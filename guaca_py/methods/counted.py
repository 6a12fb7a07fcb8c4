"""Counted storage: Dynamic Fragment Buffer, S-buffer (two geometry passes) and paged linked lists.

dfb and sbuffer count the fragments of each pixel in a first geometry pass, turn the counts into
per-pixel ranges of one fragment array sized exactly to the frame's total (read back as one
word), and store the shaded-later payload of every fragment in a second pass. paged_ll stores
into pages of P fragments linked per pixel in a single pass and grows its page pool on overflow.
All three resolve by sorting each pixel's fragments by (depth, tie id) in the composite pass.
"""

from __future__ import annotations

import math

import numpy as np

from ..gpu_counters import CounterBlock, StagedReader
from ..pipeline.settings import Setting, non_negative, positive
from ..prefix_sum import GpuFill, PrefixSum, dispatch_grid
from ..shaders import set_uniform
from ..shaders.slots import Buffer
from .base import TransparencyMethod
from .presort_lf import _budget

PAYLOAD_BYTES = 32  # common/payload_pack.glsl.j2: 8 words per fragment
COUNTERS = ("stored", "overflow", "alloc", "wasted_pages", "guard")


def _chunk(v) -> str | None:
    return None if 1 <= v <= 256 else f"must be in 1..256, got {v}"


def _counters_check(v) -> str | None:
    return None if 1 <= v <= 65536 else f"must be in 1..65536, got {v}"


def _page_check(v) -> str | None:
    return None if 1 <= v <= 64 else f"must be in 1..64, got {v}"


class _CountedStorage(TransparencyMethod):
    """Shared storage, counters, GL state and resolve of the counted-storage methods."""

    antialiasing_refusal = "its counted records carry no coverage mask (counting and storing passes are per pixel)"

    layout: str = ""
    SETTINGS = {
        "budget_mb": Setting(
            (str, int, float), "auto", "cap on fragment storage in MB, or 'auto' (the frame's need)", check=_budget
        ),
        "sort_chunk": Setting((int,), 32, "fragments sorted per resolve sweep (local array size)", check=_chunk),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self.phase = "resolve"
        self._pixels = 0
        self._bufs: dict = {}
        self._scan = self._fill = None
        self._counters: CounterBlock | None = None
        self._reader: StagedReader | None = None
        self._last: dict = {}

    # ------------------------------------------------------------------ helpers
    def _tools(self, frame) -> None:
        if self._scan is None:
            self._scan = PrefixSum(frame.ctx, frame.renderer.shaders)
            self._fill = GpuFill(frame.renderer.shaders)
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

    def _read_counters(self) -> dict:
        return self._counters.read()

    def _state_begin(self, frame) -> None:
        """Transparent draws test against the opaque depth without writing it."""
        mgl = frame.renderer.moderngl
        g = frame.resources["gbuffer"]
        g["depth_only"].use()
        g["depth_only"].depth_mask = False
        frame.ctx.enable(mgl.DEPTH_TEST)
        frame.ctx.depth_func = "<"

    def _draw(self, frame, phase: str, uniforms: dict) -> None:
        self.phase = phase
        self._bind()
        frame.draw_transparent(uniforms)
        frame.ctx.memory_barrier()

    def _bind(self) -> None:
        for binding, name in self._bindings().items():
            if name == "counters":
                self._counters.bind(binding)
            else:
                self._bufs[name].bind_to_storage_buffer(binding)

    def _bindings(self) -> dict[int, str]:
        raise NotImplementedError

    def _warn(self, frame, text: str) -> None:
        frame.stats.setdefault("warnings", []).append(text)

    # ------------------------------------------------------------------ shaders
    _PHASE_TEMPLATES = {
        "count": "counted/count.glsl.j2",
        "store": "counted/store.glsl.j2",
        "insert": "counted/paged_insert.glsl.j2",
    }
    first_phase = "count"

    def fragment_template(self) -> str:
        """The current geometry phase's code (count, store or paged insert)."""
        return self._PHASE_TEMPLATES.get(self.phase, self._PHASE_TEMPLATES[self.first_phase])

    def template_vars(self) -> dict:
        """Storage layout, the current phase (count/store/insert/resolve) and the sort chunk."""
        return {"cs_layout": self.layout, "phase": self.phase, "sort_chunk": int(self.settings["sort_chunk"])}

    def resolve_template(self) -> str:
        """Chunked sort + front-to-back blend of each pixel's fragments."""
        return "counted/resolve.glsl.j2"

    def bind_composite(self, frame, program) -> None:
        """The composite reads the same storage."""
        self.phase = "resolve"
        self._bind()
        set_uniform(program, "gua_cs_capacity", self._capacity_uniform())

    def _capacity_uniform(self) -> int:
        raise NotImplementedError

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


class DynamicFragmentBuffer(_CountedStorage):
    """DFB: count pass, GPU prefix sum over all pixels, exact allocation, store pass, sort at resolve."""

    id = "dfb"
    exact = True
    geometry_passes = "2"
    summary = "dynamic fragment buffer: count, prefix sum, exact per-pixel arrays, sort at resolve"
    layout = "dfb"

    def _bindings(self) -> dict[int, str]:
        return {
            Buffer.COUNTED_PIXELS: "pixels",
            Buffer.COUNTED_NODES: "nodes",
            Buffer.COUNTED_COUNTS: "counts",
            Buffer.COUNTED_COUNTERS: "counters",
        }

    def _capacity_uniform(self) -> int:
        return self._last.get("capacity", 0)

    def _pixel_buffers(self, frame) -> None:
        """Per-pixel buffers of this layout (resized with the frame)."""
        n = frame.pixel_count
        self._buffer(frame.ctx, "pixels", (n + 1) * 4)

    def prepare(self, frame) -> None:
        """Size per-pixel buffers, zero the counts and counters."""
        self._tools(frame)
        ctx, n = frame.ctx, frame.pixel_count
        self._pixels = n
        self._pixel_buffers(frame)
        self._buffer(ctx, "counts", n * 4)
        if "nodes" not in self._bufs:
            self._buffer(ctx, "nodes", PAYLOAD_BYTES)  # sized to the frame's total before the store pass
        self._fill.run(self._bufs["counts"], n, 0)
        self._reset_counters(ctx)
        ctx.memory_barrier()

    def _addresses(self, frame) -> int:
        """Per-pixel offsets from the counts; returns the frame's fragment total (one word read back)."""
        n = frame.pixel_count
        self._scan.run(self._bufs["counts"], self._bufs["pixels"], n)
        return int(np.frombuffer(self._reader.read(self._bufs["pixels"], 4, n * 4), dtype=np.uint32)[0])

    def render_transparent(self, frame) -> None:
        """Count pass, addressing, exact allocation, store pass."""
        self._state_begin(frame)
        self._draw(frame, "count", {})
        total = self._addresses(frame)
        capacity = min(total, self._max_slots(frame.ctx, PAYLOAD_BYTES))
        self._buffer(frame.ctx, "nodes", capacity * PAYLOAD_BYTES)
        self._last = {"total": total, "capacity": capacity}
        if total:
            self._draw(frame, "store", {"gua_cs_capacity": capacity})
        self.phase = "resolve"
        frame.resources["gbuffer"]["fbo"].depth_mask = True

    def finish(self, frame) -> bool:
        """Read the counters into frame.stats (exact allocation: never asks for a re-render)."""
        c = self._read_counters()
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

    def memory(self) -> dict:
        """Per-pixel counts and offsets, fragment array (allocated == the frame's need), scan buffers."""
        if not self._bufs:
            return {}
        return {
            "counted_counts": self._bufs["counts"].size,
            "counted_offsets": self._bufs["pixels"].size,
            "counted_fragments": self._bufs["nodes"].size,
            "counted_fragments_used": self._last.get("stored", 0) * PAYLOAD_BYTES,
            "counted_scan_aux": self._scan.aux_bytes() if self._scan else 0,
            "counted_node_bytes": PAYLOAD_BYTES,
        }


class SBuffer(DynamicFragmentBuffer):
    """S-buffer: as dfb, but pixels reserve their ranges from S counters; only the S totals are scanned."""

    id = "sbuffer"
    summary = "S-buffer: count, S shared counters + scan of the counters, exact arrays, sort at resolve"
    layout = "sbuffer"
    SETTINGS = {
        **_CountedStorage.SETTINGS,
        # Vasilakis & Fudos report about 30 counters as the sweet spot (survey §3.4).
        "counters": Setting((int,), 32, "S: address counters shared by pixel p mod S", check=_counters_check),
    }

    def _bindings(self) -> dict[int, str]:
        return {
            Buffer.COUNTED_PIXELS: "pixels",
            Buffer.COUNTED_NODES: "nodes",
            Buffer.COUNTED_COUNTS: "counts",
            Buffer.COUNTED_COUNTERS: "counters",
            Buffer.COUNTED_GROUP_BASE: "group_base",
        }

    def template_vars(self) -> dict:
        """Adds the number of counters S."""
        return {**super().template_vars(), "counters": int(self.settings["counters"])}

    def _pixel_buffers(self, frame) -> None:
        s = int(self.settings["counters"])
        self._buffer(frame.ctx, "pixels", frame.pixel_count * 8)
        self._buffer(frame.ctx, "groups", s * 4)
        self._buffer(frame.ctx, "group_base", (s + 1) * 4)

    def _addresses(self, frame) -> int:
        """Ranges from S atomic counters, then a scan of the S group totals; returns the total."""
        s, n = int(self.settings["counters"]), frame.pixel_count
        self._fill.run(self._bufs["groups"], s, 0)
        frame.ctx.memory_barrier()
        prog = frame.renderer.shaders.compute("counted/sbuffer_address.comp.j2", counters=s)
        self._bufs["pixels"].bind_to_storage_buffer(Buffer.COUNTED_PIXELS)
        self._bufs["counts"].bind_to_storage_buffer(Buffer.COUNTED_COUNTS)
        self._bufs["groups"].bind_to_storage_buffer(Buffer.COUNTED_GROUPS)
        prog["gua_pixel_count"] = n
        prog.run(*dispatch_grid(math.ceil(n / 256)))
        frame.ctx.memory_barrier()
        self._scan.run(self._bufs["groups"], self._bufs["group_base"], s)
        return int(np.frombuffer(self._reader.read(self._bufs["group_base"], 4, s * 4), dtype=np.uint32)[0])

    def memory(self) -> dict:
        """As dfb, plus the S counters and group offsets."""
        out = super().memory()
        if out:
            out["counted_groups"] = self._bufs["groups"].size + self._bufs["group_base"].size
        return out


class PagedLinkedLists(_CountedStorage):
    """paged_ll: one geometry pass into per-pixel linked pages of P fragments; the page pool grows on overflow."""

    id = "paged_ll"
    exact = True
    geometry_passes = "1"
    summary = "paged per-pixel linked lists (P fragments per page), lock-free, sort at resolve"
    layout = "paged"
    first_phase = "insert"
    SETTINGS = {
        **_CountedStorage.SETTINGS,
        "page_size": Setting((int,), 4, "P: fragments per page", check=_page_check),
        "max_regrow": Setting(
            (int,), 2, "re-renders allowed to grow an 'auto' pool after overflow", check=non_negative
        ),
        "max_steps": Setting((int,), 4096, "bound on retries per insertion (guards against livelock)", check=positive),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self.page = int(settings["page_size"])
        self.fill_bits = max(1, self.page.bit_length())  # holds 0..P
        self.page_bytes = self.page * PAYLOAD_BYTES + 4  # payload slots + link
        self.capacity = 0  # pages in the pool, null page 0 included
        self._want = 0  # pool size requested for the next prepare()

    def _bindings(self) -> dict[int, str]:
        return {
            Buffer.COUNTED_PIXELS: "pixels",
            Buffer.COUNTED_NODES: "nodes",
            Buffer.COUNTED_LINKS: "links",
            Buffer.COUNTED_COUNTERS: "counters",
        }

    def _capacity_uniform(self) -> int:
        return self.capacity

    def template_vars(self) -> dict:
        """Adds page size, fill bits and the retry bound."""
        return {
            **super().template_vars(),
            "page_size": self.page,
            "fill_bits": self.fill_bits,
            "max_steps": int(self.settings["max_steps"]),
        }

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

    def prepare(self, frame) -> None:
        """Size the page pool (requested size, previous size or a first guess), clear heads and counters."""
        self._tools(frame)
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

    def render_transparent(self, frame) -> None:
        """One geometry pass: every fragment appends itself to its pixel's pages."""
        self._state_begin(frame)
        self._draw(frame, "insert", {"gua_cs_capacity": self.capacity})
        self.phase = "resolve"
        frame.resources["gbuffer"]["fbo"].depth_mask = True

    def finish(self, frame) -> bool:
        """Read counters; with an 'auto' budget grow the pool after overflow and ask for a re-render."""
        c = self._read_counters()
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
        auto = self.settings["budget_mb"] == "auto"
        limit = self._page_limit(frame.ctx)
        regrown = frame.stats.get("regrown", 0)  # re-renders of this frame so far
        if c["overflow"] and auto and regrown < self.settings["max_regrow"] and self.capacity < limit:
            # Every dropped fragment asked for at most one page, so `requested` bounds the need
            # from above (by up to P times: measured 5.2M pages asked, 1.18M needed); fragments of
            # one pixel share pages, so used + overflow / P bounds it from below. Grow to the lower
            # bound and take the upper one on the last re-render max_regrow allows.
            last = regrown + 1 >= self.settings["max_regrow"]
            need = requested if last else used + math.ceil(c["overflow"] / self.page)
            self._want = min(limit, int(need * 1.15) + 1024)
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
        target = max(1024, int(used * 1.15) + 1024)
        if auto and not c["overflow"] and self.capacity > 2 * target:
            self._want = target  # shrink for the next frame (this frame still reads the current pool)
        return False

    def memory(self) -> dict:
        """Heads, page pool (allocated and used, links included) and the bytes of stored payload."""
        if not self._bufs:
            return {}
        used = self._last.get("used_pages", 0)
        return {
            "counted_heads": self._pixels * 4,
            "counted_pages": self.capacity * self.page_bytes,
            "counted_pages_used": (used + 1) * self.page_bytes,
            "counted_fragments_used": self._last.get("stored", 0) * PAYLOAD_BYTES,
            "counted_node_bytes": PAYLOAD_BYTES,
        }
