"""PreSortLF / PreSortLF*: sorted lock-free A-buffer insertion (optionally with early termination)."""

from __future__ import annotations

import math
import os

from ..gpu_counters import CounterBlock
from ..limits import pool_node_limit
from ..pipeline.settings import Setting, non_negative, positive
from ..shaders import set_uniform, set_uniforms
from ..shaders.slots import Buffer, Image
from .base import TransparencyMethod

NODE_PAYLOAD_BYTES = 32  # depth + 7 payload words, see abuffer/layout.glsl.j2
COUNTERS = ("alloc", "unlinked", "et_dropped", "et_culled", "guard")  # abuffer/layout.glsl.j2, same order
_INT64_EXT = "#extension GL_ARB_gpu_shader_int64 : require\n#extension GL_NV_shader_atomic_int64 : require\n"
_BALLOT_EXT = "#extension GL_ARB_gpu_shader_int64 : require\n#extension GL_ARB_shader_ballot : require\n"


def _budget(v) -> str | None:
    if v == "auto" or (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
        return None
    return f"must be 'auto' or a positive number of MB, got {v!r}"


class PreSortLF(TransparencyMethod):
    """Per-pixel lists kept sorted at insertion by lock-free CAS (32-bit) or atomicMax (64-bit)."""

    id = "presort_lf"
    exact = True
    geometry_passes = "1"
    early_termination = False
    summary = "sorted lock-free insertion into per-pixel lists (no early termination)"
    compute_raster = True  # insertion is gua_submit_at(pix, depth, tie): callable from compute kernels
    supports_antialiasing = True  # nodes carry the coverage mask; the composite resolves per sample
    counters: tuple[str, ...] = COUNTERS  # counter words of the counter buffer, in layout order
    extra_slots = 0  # per-pixel link words after the node links (second list heads, locks)
    SETTINGS = {
        "budget_mb": Setting(
            (str, int, float), "auto", "node pool size in MB, or 'auto' (grow to the need)", check=_budget
        ),
        "max_regrow": Setting(
            (int,), 4, "re-renders allowed to grow an 'auto' pool after overflow", check=non_negative
        ),
        "max_steps": Setting(
            (int,), 4096, "bound on list steps per insertion (guards against livelock)", check=positive
        ),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self.path = caps.insertion_path
        self.link_bytes = 8 if self.path == "64bit" else 4
        self.node_bytes = NODE_PAYLOAD_BYTES + self.link_bytes
        self._links = self._nodes = self._counters = self._cull = None
        self._pixels = 0
        self.capacity = 0  # nodes in the pool, node 0 included
        self.regrown = 0
        self._want = 0  # pool size requested for the next prepare()
        self._last = {}
        self._counts: dict[str, int] | None = None

    # ------------------------------------------------------------------ storage
    def _initial_capacity(self, pixels: int) -> int:
        if self.settings["budget_mb"] != "auto":
            return max(2, int(self.settings["budget_mb"] * 1024 * 1024) // self.node_bytes)
        return max(1024, pixels)  # one node per pixel; grown to the measured need on overflow

    def max_capacity(self, pixels: int) -> int:
        """Most nodes the device's storage rule allows for this frame size (guaca_py/limits.py)."""
        return pool_node_limit(self.caps.limits, pixels * (1 + self.extra_slots), self.link_bytes, NODE_PAYLOAD_BYTES)

    def _overflow_hint(self) -> str:
        """What to do about an overflow, from what bounded the pool."""
        if self.capacity >= self.max_capacity(self._pixels):
            et = "" if self.early_termination else ", or use a method with early termination (presort_lf_et)"
            return (
                f"the pool is at the device's limit ({self.caps.limits.describe()}); render fewer layers or pixels{et}"
            )
        if self.settings["budget_mb"] != "auto":
            return "raise transparency.budget_mb or use 'auto'"
        return "raise transparency.max_regrow"

    def _alloc(self, ctx, pixels: int, capacity: int, size) -> None:
        capacity = min(capacity, self.max_capacity(pixels))
        if self._links is None or self._pixels != pixels or self.capacity != capacity:
            self.release()
            self._pixels, self.capacity = pixels, capacity
            self._links = ctx.buffer(reserve=(pixels * (1 + self.extra_slots) + capacity) * self.link_bytes)
            self._nodes = ctx.buffer(reserve=capacity * NODE_PAYLOAD_BYTES)
            self._counters = CounterBlock(ctx, self.counters)
            self._cull = ctx.texture(size, 1, dtype="u4")

    def prepare(self, frame) -> None:
        """Size the pool, clear list heads, counters and the saturation depth."""
        if self._want:
            cap, self._want = self._want, 0
        elif self._pixels == frame.pixel_count and self.capacity:
            cap = self.capacity
        else:
            cap = self._initial_capacity(frame.pixel_count)
        self._alloc(frame.ctx, frame.pixel_count, cap, (frame.width, frame.height))
        self._counters.reset(alloc=1)  # node 0 is the null link
        self._counts = None
        clear = frame.renderer.shaders.compute("abuffer/clear.comp.j2")
        self._links.bind_to_storage_buffer(Buffer.ABUFFER_LINKS)
        self._cull.bind_to_image(Image.CULL_DEPTH, read=False, write=True)
        set_uniforms(
            clear,
            (
                ("gua_size", (frame.width, frame.height)),
                ("gua_words_per_link", self.link_bytes // 4),
                ("gua_extra_base", frame.pixel_count + self.capacity),
                ("gua_extra_slots", self.extra_slots),
            ),
        )
        clear.run(math.ceil(frame.width / 16), math.ceil(frame.height / 16), 1)
        frame.ctx.memory_barrier()

    def _bind(self) -> None:
        self._links.bind_to_storage_buffer(Buffer.ABUFFER_LINKS)
        self._nodes.bind_to_storage_buffer(Buffer.ABUFFER_NODES)
        self._counters.bind(Buffer.ABUFFER_COUNTERS)

    def threshold(self) -> float:
        """Insertion saturation threshold; above 1 means never saturate."""
        return float(self.settings["threshold"]) if self.early_termination else 2.0

    def render_transparent(self, frame) -> None:
        """One geometry pass: every transparent fragment tries to insert itself."""
        mgl = frame.renderer.moderngl
        g = frame.resources["gbuffer"]
        g["depth_only"].use()
        g["depth_only"].depth_mask = False  # hardware test against opaque depth only
        frame.ctx.enable(mgl.DEPTH_TEST)
        frame.ctx.depth_func = "<"
        self._bind()
        self._cull.bind_to_image(Image.CULL_DEPTH, read=True, write=True)
        frame.draw_transparent(
            {
                "gua_ab_capacity": self.capacity,
                "gua_pixel_count": frame.pixel_count,
                "gua_ab_threshold": self.threshold(),
            }
        )
        g["fbo"].depth_mask = True

    def finish(self, frame) -> bool:
        """Read counters; with an 'auto' budget, grow the pool to the need and ask for a re-render.

        In a frame loop without read-back (frame.late_counters) the counters of the previous frame
        are read instead, which needs no wait: an overflow they show grows the pool for the next
        frame and is reported, but the frame is not rendered again.
        """
        c, staged_capacity, late = self._counters.latest(frame.late_counters)
        self._counts = c  # after_composite() reads these again
        capacity = staged_capacity if late else self.capacity
        if late:
            frame.stats["fragments_of"] = "previous frame"
        requested = c["alloc"] - 1  # node 0 is the null node
        used = min(requested, capacity - 1)
        # allocations past the pool failed (overflow); the others were linked unless counted unlinked
        c["overflow"] = requested - used
        stored = used - c["unlinked"]
        frame.stats["fragments"] = {
            "stored": stored,
            "overflow": c["overflow"],
            "et_dropped": c["et_dropped"],
            "et_culled": c["et_culled"],
            "early_termination_culled": c["et_dropped"] + c["et_culled"],
            "guard_abandoned": c["guard"],
            "nodes_requested": requested,
        }
        self._last = {"used_nodes": used}
        if c["overflow"]:
            frame.stats.setdefault("warnings", []).append(
                f"A-buffer overflow{' in the previous frame' if late else ''}: {c['overflow']} fragments dropped "
                f"(pool {capacity - 1} nodes, frame asked for {requested}); {self._overflow_hint()}"
            )
        if c["guard"]:
            frame.stats.setdefault("warnings", []).append(f"{c['guard']} insertions hit max_steps and were dropped")
        auto = self.settings["budget_mb"] == "auto"
        grow = self.capacity < self.max_capacity(self._pixels)
        if c["overflow"] and auto and late:
            self.capacity_request(int(requested * 1.15) + 1024)  # for the next frame
            return False
        if c["overflow"] and auto and self.regrown < self.settings["max_regrow"] and grow:
            self.regrown += 1
            self.capacity_request(int(requested * 1.15) + 1024)
            return True
        target = max(1024, int(requested * 1.15) + 1024)
        if auto and not c["overflow"] and target * 3 < self.capacity * 2:
            # hold what the scene needs: shrink for the next frame once a third of the pool idles
            # (growth adds 15%, so a steady scene does not oscillate)
            self.capacity_request(target)
        self.regrown = 0  # max_regrow bounds the re-renders of one frame, not of the renderer's life
        return False

    def after_composite(self, frame) -> None:
        """In a frame loop without read-back, set this frame's counters aside for the next frame's finish()."""
        if frame.late_counters:
            self._counters.stage(self.capacity)

    def read_counters(self, fresh: bool = False) -> dict[str, int]:
        """This frame's counters by name (one small GPU-side copy, then a read of the copy)."""
        if self._counts is None or fresh:
            self._counts = self._counters.read()
        return self._counts

    def capacity_request(self, nodes: int) -> None:
        """Resize the pool at the next prepare() (the current frame keeps reading this one), within the device's limit.

        With early termination an overflowed frame asks for more than it needs (dropped fragments
        saturate nothing, so the fragments behind them ask for nodes too; measured on a 300-layer
        front-to-back stack: 1.2M asked, 45k needed), so growth is bounded to 4x per re-render there
        except on the last re-render max_regrow allows, which takes the whole request so the frame
        is complete; without early termination the request is exact.
        """
        last = self.regrown >= self.settings["max_regrow"]
        if self.early_termination and nodes > self.capacity and not last:
            nodes = min(nodes, 4 * max(self.capacity, 1024))
        self._want = min(nodes, self.max_capacity(self._pixels))

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """Insertion code."""
        return "abuffer/insert_lockfree.glsl.j2"

    def resolve_template(self) -> str:
        """Sorted list walk."""
        return "abuffer/resolve_sorted.glsl.j2"

    def template_vars(self) -> dict:
        """Insertion path and loop bound."""
        ballot = self.caps.shader_ballot
        return {
            "ab_path": self.path,
            "max_steps": int(self.settings["max_steps"]),
            "subgroup_counts": ballot,
            "subgroup_alloc": ballot and self.path == "64bit",
            "aa_samples": self.aa_samples,
            # the 64-bit walk spends an atomicMax per node it passes (GUACA_ATOMIC_WALK=1, to measure
            # against the default: a plain load per node passed, an atomic only where it may insert)
            "atomic_walk": os.environ.get("GUACA_ATOMIC_WALK", "") not in ("", "0"),
            # profiling only (GUACA_SKIP_INSERTION=1): fragments are rasterized and shaded but never
            # inserted, so a frame's time is what the rasterizer costs without the A-buffer
            "skip_insertion": os.environ.get("GUACA_SKIP_INSERTION", "") not in ("", "0"),
        }

    def extensions(self) -> str:
        """64-bit atomics where the path uses them."""
        return (_INT64_EXT if self.path == "64bit" else "") + (_BALLOT_EXT if self.caps.shader_ballot else "")

    def bind_composite(self, frame, program) -> None:
        """The composite walks the same lists."""
        self._bind()
        for name, value in (
            ("gua_ab_capacity", self.capacity),
            ("gua_pixel_count", frame.pixel_count),
            ("gua_ab_threshold", self.threshold()),
        ):
            set_uniform(program, name, value)

    def composite_threshold(self) -> float:
        """Without early termination the walk only stops at full opacity."""
        return float(self.settings["threshold"]) if self.early_termination else 1.0

    def memory(self) -> dict:
        """Heads, pool (allocated and used), counters and saturation-depth image, in bytes."""
        if self._links is None and not self._pixels:
            return {}
        used = self._last.get("used_nodes", 0)
        return {
            "abuffer_heads": self._pixels * self.link_bytes,
            "abuffer_pool": self.capacity * self.node_bytes,
            "abuffer_pool_used": (used + 1) * self.node_bytes,
            "abuffer_cull_depth": self._pixels * 4,
            "abuffer_node_bytes": self.node_bytes,  # coverage masks ride in free payload bits: same size
        }

    def release(self) -> None:
        """Free all buffers."""
        for b in (self._links, self._nodes, self._counters, self._cull):
            if b is not None:
                b.release()
        self._links = self._nodes = self._counters = self._cull = None


class PreSortLFET(PreSortLF):
    """PreSortLF* — the default: insertion stops once the pixel is saturated in front of the fragment."""

    id = "presort_lf_et"
    early_termination = True
    summary = "sorted lock-free insertion with early termination (guacamole's default)"
