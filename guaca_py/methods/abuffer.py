"""The exact one-pass A-buffer methods (Schneegans et al. 2015, §5): one class, one record of options each.

Every transparent fragment becomes a node of one pool, linked into its pixel's list; the methods
differ only in how a node enters the list and how the composite walks it:

| method | insertion | composite |
|---|---|---|
| presort_lf, presort_lf_et | sorted and lock-free: CAS on 32-bit links, or atomicMax on 64-bit (depth, node) records (Lefebvre et al. 2014) | the sorted list |
| presort_lf_merge2_et | the same into one of two lists per pixel (half the walk and contention) | both lists merged front to back |
| presort_cs, presort_cs_et | sorted inside a per-pixel critical section (fragment shader interlock or spin lock) | the sorted list |
| post_sort | unsorted (head swap) | sorted in a fixed local array (the nearest kept) |
| post_merge16 | unsorted (head swap) | exact order, by rounds of the 16 nearest |

With early termination (the `_et` methods, presort_lf_et being the default) an insertion stops
once the pixel is saturated in front of the fragment. All share the node pool, payload, counters,
overflow reporting and 'auto' growth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl

from ..gpu_counters import CounterBlock
from ..growth import idles, with_margin
from ..limits import pool_node_limit
from ..pipeline.settings import Setting, auto_or_positive_mb, non_negative, positive
from ..raster.choice import compute_kernels_draw
from ..registry import register
from ..shaders import set_uniform, set_uniforms
from ..shaders.slots import Buffer, Image
from .base import LOCK_SETTING, MethodSpec, TransparencyMethod, resolve_lock
from .shared_pool import ViewsNeed

NODE_PAYLOAD_BYTES = 32  # depth + 7 payload words, see abuffer/layout.glsl.j2
COUNTERS = ("alloc", "unlinked", "et_dropped", "et_culled", "guard")  # abuffer/layout.glsl.j2, same order
# counter words of the other insertions, in the order of abuffer/variants_common.glsl.j2
VARIANT_COUNTERS = COUNTERS + ("lock_abandoned", "truncated", "truncated_pixels")
POST_MERGE_CHUNK = 16  # post_merge16: nearest fragments ordered per round of the composite
_INT64_EXT = "#extension GL_ARB_gpu_shader_int64 : require\n#extension GL_NV_shader_atomic_int64 : require\n"
_BALLOT_EXT = "#extension GL_ARB_gpu_shader_int64 : require\n#extension GL_ARB_shader_ballot : require\n"
_INTERLOCK_EXT = "#extension GL_ARB_fragment_shader_interlock : require\n"
_INSERT_TEMPLATES = {
    "sorted": "abuffer/insert_lockfree.glsl.j2",
    "two_lists": "abuffer/insert_two_lists.glsl.j2",  # the list picked by tie-id parity
    "critical": "abuffer/insert_critical.glsl.j2",
    "unsorted": "abuffer/insert_unsorted.glsl.j2",
}
_RESOLVE_TEMPLATES = {
    "sorted": "abuffer/resolve_sorted.glsl.j2",  # lists sorted by (depth, tie)
    "two_lists": "abuffer/resolve_two_lists.glsl.j2",
    "post_sort": "abuffer/resolve_post_sort.glsl.j2",
    "post_merge16": "abuffer/resolve_post_merge.glsl.j2",
}


def _array_size(v) -> str | None:
    return None if 1 <= v <= 256 else f"must be in 1..256 (a local array of the composite shader), got {v}"


@dataclass(frozen=True)
class ABufferKind:
    """What one A-buffer method chooses: its insertion, its composite walk and early termination."""

    insertion: str  # a key of _INSERT_TEMPLATES
    resolve: str  # a key of _RESOLVE_TEMPLATES
    early_termination: bool = False


class ABuffer(TransparencyMethod):
    """Per-pixel lists of nodes in one pool, filled in one geometry pass and walked by the composite."""

    compute_raster = True  # insertion is gua_submit_at(pix, depth, tie): callable from compute kernels
    supports_antialiasing = True  # nodes carry the coverage mask; the composite resolves per sample

    def __init__(self, spec, settings, caps):
        super().__init__(spec, settings, caps)
        self.kind: ABufferKind = spec.options
        self.early_termination = self.kind.early_termination
        # counter words of the counter buffer, in layout order
        self.counters = COUNTERS if self.kind.insertion == "sorted" else VARIANT_COUNTERS
        self.lock: str | None = None  # the critical section, where the insertion takes one
        # per-pixel link words after the node links (second list heads, locks)
        self.extra_slots = 1 if self.kind.insertion == "two_lists" else 0
        if self.kind.insertion == "critical":
            self.lock = self._critical_section(settings, caps)
            self.extra_slots = 1 if self.lock == "spin" else 0  # one lock word per pixel
        # plain 32-bit node links where no 64-bit atomics are needed: the critical section orders
        # the list, and unsorted gathering is one 32-bit atomicExchange per fragment
        self.path = "32bit" if self.kind.insertion in ("critical", "unsorted") else caps.insertion_path
        self.link_bytes = 8 if self.path == "64bit" else 4
        self.node_bytes = NODE_PAYLOAD_BYTES + self.link_bytes
        self._links = self._nodes = self._counters = self._cull = None
        self._pixels = 0
        self.capacity = 0  # nodes in the pool, node 0 included
        self._want = 0  # pool size requested for the next prepare()
        self._views_need = ViewsNeed()  # the views of one render_views() call share the pool
        self._last = {}
        self._counts: dict[str, int] | None = None

    def _critical_section(self, settings, caps) -> str:
        """'interlock' or 'spin' for the `lock` setting on this device and rasterizer."""
        lock = settings["lock"]
        if lock == "auto" and compute_kernels_draw(settings.get("raster"), caps):
            # the interlock exists only in fragment shaders, and the compute rasterizer with the
            # spin lock was the faster pair on every Table 1 scene on the H100 (presort_cs_et,
            # docs/decisions.md, 2026-11-23 "presort_cs takes the spin lock": dragons 7.7 against
            # 20.5 ms, Sponza v1 3.3 against 11.5, v2 3.5 against 13.6, hairball_v1 11.1 against 123)
            lock = "spin"
            if settings.get("raster") == "auto":
                # draws of large triangles too: a contended spin lock in a fragment shader
                # serializes badly (base.resolve_lock), the compute kernels handle every size
                self.auto_compute_reason = f"method '{self.id}': lock auto took the spin lock for compute kernels"
        return resolve_lock(self.id, lock, caps)

    def compute_raster_refusal(self) -> str | None:
        """The fragment shader interlock has no compute counterpart; the spin lock has."""
        if self.lock == "interlock":
            return "its critical section is the fragment shader interlock (set lock: spin)"
        return super().compute_raster_refusal()

    # ------------------------------------------------------------------ storage
    def _initial_capacity(self, pixels: int) -> int:
        if self.settings["budget_mb"] != "auto":
            return max(2, int(self.settings["budget_mb"] * 1024 * 1024) // self.node_bytes)
        return max(1024, pixels)  # one node per pixel; grown to the measured need on overflow

    def max_capacity(self, pixels: int) -> int:
        """Most nodes the device's storage rule allows for this frame size (guaca_py/limits.py)."""
        return pool_node_limit(self.caps.limits, pixels * (1 + self.extra_slots), self.link_bytes, NODE_PAYLOAD_BYTES)

    def pool_fragments(self, pixels: int) -> int:
        """Most fragments the pool can store for a frame of `pixels` rendered pixels: its largest size less node 0."""
        return self.max_capacity(pixels) - 1  # node 0 is the null link

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
        clear = frame.programs.compute("abuffer/clear.comp.j2")
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
        mgl = moderngl
        g = frame.resources["gbuffer"]
        g.depth_only.use()
        g.depth_only.depth_mask = False  # hardware test against opaque depth only
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
        g.fbo.depth_mask = True

    def finish(self, frame) -> bool:
        """Read counters; with an 'auto' budget, grow the pool to the need and ask for a re-render.

        In a frame loop without read-back (frame.late_counters) the counters of the previous frame
        are read instead, which needs no wait: an overflow they show grows the pool for the next
        frame and is reported, but the frame is not rendered again.
        """
        again = self._read_pool(frame)
        if "lock_abandoned" in self.counters:  # the insertions of abuffer/variants_common.glsl.j2
            frame.stats["geometry_passes"] = 1
            abandoned = self.read_counters()["lock_abandoned"]
            frame.stats["fragments"]["lock_abandoned"] = abandoned
            if abandoned:
                frame.stats.warn(
                    f"{abandoned} fragments gave up waiting for their pixel's lock (max_spin) and were dropped"
                )
        if self.lock is not None:
            frame.stats["critical_section"] = self.lock
        return again

    def _read_pool(self, frame) -> bool:
        """Counters into frame.stats and warnings; pool growth (for this frame or the next); whether to re-render."""
        c, staged_capacity, late = self._counters.latest(frame.late_counters, frame.view_index)
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
            frame.stats.warn(
                f"A-buffer overflow{' in the previous frame' if late else ''}: {c['overflow']} fragments dropped "
                f"(pool {capacity - 1} nodes, frame asked for {requested}); {self._overflow_hint()}"
            )
        if c["guard"]:
            frame.stats.warn(f"{c['guard']} insertions hit max_steps and were dropped")
        largest = self._views_need(frame, requested)  # of this call's views, known at its last
        auto = self.settings["budget_mb"] == "auto"
        grow = self.capacity < self.max_capacity(self._pixels)
        redraws = frame.stats.get("regrown", 0)  # re-draws of this frame so far (pipeline/retry.py)
        if c["overflow"] and auto and late:
            self.capacity_request(with_margin(requested))  # for the next frame
            return False
        if c["overflow"] and auto and redraws < self.settings["max_regrow"] and grow:
            self.capacity_request(with_margin(requested), last=redraws + 1 >= self.settings["max_regrow"])
            return True
        if auto and largest is not None and not c["overflow"] and idles(self.capacity, largest):
            # hold what the scene needs (growth.py); with several views, what the largest of them
            # needs (methods/shared_pool.py)
            self.capacity_request(with_margin(largest))
        return False

    def after_composite(self, frame) -> None:
        """Set this frame's counters aside for the next frame's finish() in a frame loop without
        read-back; unsorted lists report what the composite's walk left out (truncation)."""
        if self.kind.insertion != "unsorted":
            if frame.late_counters:
                self._counters.stage(self.capacity, frame.view_index)
            return
        frame.ctx.memory_barrier()
        if frame.late_counters:  # the previous frame's counts (read in finish), this frame's set aside
            self._counters.stage(self.capacity, frame.view_index)
            c = self.read_counters()
        else:
            c = self.read_counters(fresh=True)  # the composite counted after the geometry read
        fr = frame.stats.setdefault("fragments", {})
        fr["truncated"], fr["truncated_pixels"] = c["truncated"], c["truncated_pixels"]
        if c["truncated"]:
            frame.stats.warn(self._truncation_warning(c))

    def _truncation_warning(self, c: dict) -> str:
        if self.kind.resolve == "post_sort":
            return (
                f"post_sort truncated {c['truncated']} fragments in {c['truncated_pixels']} pixels deeper than "
                f"max_fragments={self.settings['max_fragments']} (the nearest were kept); raise max_fragments"
            )
        return (
            f"composite truncated {c['truncated']} fragments in {c['truncated_pixels']} pixels "
            f"(list walk bound max_steps={self.settings['max_steps']})"
        )

    def read_counters(self, fresh: bool = False) -> dict[str, int]:
        """This frame's counters by name (one small GPU-side copy, then a read of the copy)."""
        if self._counts is None or fresh:
            self._counts = self._counters.read()
        return self._counts

    def capacity_request(self, nodes: int, last: bool = False) -> None:
        """Resize the pool at the next prepare() (the current frame keeps reading this one), within the device's limit.

        With early termination an overflowed frame asks for more than it needs (dropped fragments
        saturate nothing, so the fragments behind them ask for nodes too; measured on a 300-layer
        front-to-back stack: 1.2M asked, 45k needed), so growth is bounded to 4x per re-render there
        except on the last re-render max_regrow allows (`last`), which takes the whole request so the
        frame is complete; without early termination the request is exact.
        """
        if self.early_termination and nodes > self.capacity and not last:
            nodes = min(nodes, 4 * max(self.capacity, 1024))
        self._want = min(nodes, self.max_capacity(self._pixels))

    # ------------------------------------------------------------------ shaders
    def fragment_template(self) -> str:
        """Insertion code."""
        return _INSERT_TEMPLATES[self.kind.insertion]

    def resolve_template(self) -> str:
        """The composite's list walk."""
        return _RESOLVE_TEMPLATES[self.kind.resolve]

    def template_vars(self) -> dict:
        """Insertion path and loop bound; the lock, the composite's array size or round size where used."""
        ballot = self.caps.shader_ballot
        v = {
            "ab_path": self.path,
            "max_steps": int(self.settings["max_steps"]),
            "subgroup_counts": ballot,
            "subgroup_alloc": ballot and self.path == "64bit",
            "aa_samples": self.aa_samples,
        }
        if self.lock is not None:
            v.update(
                ab_lock=self.lock,
                max_spin=int(self.settings["max_spin"]),
                fragment_interlock=self.lock == "interlock",
            )
        if self.kind.resolve == "post_sort":
            v["max_fragments"] = int(self.settings["max_fragments"])
        elif self.kind.resolve == "post_merge16":
            v["chunk"] = POST_MERGE_CHUNK
        return v

    def extensions(self) -> str:
        """64-bit atomics where the path uses them; the fragment shader interlock where it is the critical section."""
        return (
            (_INT64_EXT if self.path == "64bit" else "")
            + (_BALLOT_EXT if self.caps.shader_ballot else "")
            + (_INTERLOCK_EXT if self.lock == "interlock" else "")
        )

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
        """Heads, pool (allocated and used), counters and saturation-depth image, in bytes; the per-pixel extra words."""
        if self._links is None and not self._pixels:
            return {}
        used = self._last.get("used_nodes", 0)
        m = {
            "abuffer_heads": self._pixels * self.link_bytes,
            "abuffer_pool": self.capacity * self.node_bytes,
            "abuffer_pool_used": (used + 1) * self.node_bytes,
            "abuffer_cull_depth": self._pixels * 4,
            "abuffer_node_bytes": self.node_bytes,  # coverage masks ride in free payload bits: same size
        }
        if self.kind.insertion == "two_lists":
            m["abuffer_heads"] = 2 * self._pixels * self.link_bytes  # both lists' heads
        if self.lock == "spin":
            m["abuffer_locks"] = self._pixels * 4
        return m

    def release(self) -> None:
        """Free all buffers."""
        for b in (self._links, self._nodes, self._counters, self._cull):
            if b is not None:
                b.release()
        self._links = self._nodes = self._counters = self._cull = None


_POOL_SETTINGS = {
    "budget_mb": Setting(
        (str, int, float), "auto", "node pool size in MB, or 'auto' (grow to the need)", check=auto_or_positive_mb
    ),
    "max_regrow": Setting((int,), 4, "re-renders allowed to grow an 'auto' pool after overflow", check=non_negative),
    "max_steps": Setting((int,), 4096, "bound on list steps per insertion (guards against livelock)", check=positive),
}
_CRITICAL_SETTINGS = {
    **_POOL_SETTINGS,
    "lock": LOCK_SETTING,
    "max_spin": Setting((int,), 65536, "lock attempts before a fragment gives up (counted, reported)", check=positive),
}
_POST_SORT_SETTINGS = {
    **_POOL_SETTINGS,
    "max_fragments": Setting(
        (int,),
        32,
        "local array size of the composite sort; farther fragments of deeper pixels are truncated (counted, reported)",
        check=_array_size,
    ),
}

for _spec in (
    MethodSpec(
        "presort_lf",
        "sorted lock-free insertion into per-pixel lists (no early termination)",
        ABuffer,
        ABufferKind("sorted", "sorted"),
        _POOL_SETTINGS,
    ),
    MethodSpec(
        "presort_lf_et",
        "sorted lock-free insertion with early termination (guacamole's default)",
        ABuffer,
        ABufferKind("sorted", "sorted", early_termination=True),
        _POOL_SETTINGS,
    ),
    MethodSpec(
        "presort_lf_merge2_et",
        "two sorted lock-free lists per pixel (half the walk and contention), merged at composite",
        ABuffer,
        ABufferKind("two_lists", "two_lists", early_termination=True),
        _POOL_SETTINGS,
    ),
    MethodSpec(
        "presort_cs",
        "sorted insertion in a per-pixel critical section (fragment shader interlock or spin lock)",
        ABuffer,
        ABufferKind("critical", "sorted"),
        _CRITICAL_SETTINGS,
    ),
    MethodSpec(
        "presort_cs_et",
        "sorted insertion in a per-pixel critical section, with early termination",
        ABuffer,
        ABufferKind("critical", "sorted", early_termination=True),
        _CRITICAL_SETTINGS,
    ),
    MethodSpec(
        "post_sort",
        "unsorted per-pixel lists sorted at composite in a fixed local array (k nearest kept)",
        ABuffer,
        ABufferKind("unsorted", "post_sort"),
        _POST_SORT_SETTINGS,
    ),
    MethodSpec(
        "post_merge16",
        "unsorted per-pixel lists ordered at composite in rounds of 16 nearest (no fixed limit)",
        ABuffer,
        ABufferKind("unsorted", "post_merge16"),
        _POOL_SETTINGS,
    ),
):
    register("method")(_spec)
