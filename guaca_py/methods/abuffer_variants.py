"""The other exact one-pass A-buffer methods of the guacamole comparison (Schneegans et al. 2015, §5).

PreSortLFMerge2* (two sorted lock-free lists per pixel), PreSortCS / PreSortCS* (sorted insertion
in a per-pixel critical section), PostSort (unsorted list, sorted in a fixed local array at
composite) and PostMerge16 (unsorted list, exact order by rounds of 16 at composite). All share
PreSortLF's node pool, payload, counters, overflow reporting and 'auto' growth.
"""

from __future__ import annotations

from ..pipeline.settings import Setting, positive
from ..raster.choice import compute_kernels_draw
from .base import LOCK_SETTING, resolve_lock
from .presort_lf import COUNTERS, NODE_PAYLOAD_BYTES, PreSortLF

# counter words after presort_lf's, in the order of abuffer/variants_common.glsl.j2
VARIANT_COUNTERS = COUNTERS + ("lock_abandoned", "truncated", "truncated_pixels")
_INTERLOCK_EXT = "#extension GL_ARB_fragment_shader_interlock : require\n"


def _array_size(v) -> str | None:
    return None if 1 <= v <= 256 else f"must be in 1..256 (a local array of the composite shader), got {v}"


class ABufferVariant(PreSortLF):
    """Shared part of the variants: extra counters, the geometry pass count, extra memory figures."""

    id = ""  # not a method by itself
    counters = VARIANT_COUNTERS

    def _use_32bit_links(self) -> None:
        """Plain 32-bit node links whatever the device (the method needs no 64-bit atomics)."""
        self.path, self.link_bytes = "32bit", 4
        self.node_bytes = NODE_PAYLOAD_BYTES + self.link_bytes

    def finish(self, frame) -> bool:
        """PreSortLF's counters and pool growth, plus this method's own counters."""
        again = super().finish(frame)
        frame.stats["geometry_passes"] = 1
        abandoned = self.read_counters()["lock_abandoned"]
        frame.stats["fragments"]["lock_abandoned"] = abandoned
        if abandoned:
            frame.stats.setdefault("warnings", []).append(
                f"{abandoned} fragments gave up waiting for their pixel's lock (max_spin) and were dropped"
            )
        return again

    def extra_memory(self) -> dict:
        """Bytes of the per-pixel link words after the node links, by name."""
        return {}

    def memory(self) -> dict:
        """PreSortLF's figures plus the extra per-pixel words."""
        m = super().memory()
        if m:
            m.update(self.extra_memory())
        return m


class PreSortLFMerge2ET(ABufferVariant):
    """PreSortLFMerge2*: two sorted lock-free lists per pixel, merged front to back at composite."""

    id = "presort_lf_merge2_et"
    early_termination = True
    extra_slots = 1  # heads of the second list
    summary = "two sorted lock-free lists per pixel (half the walk and contention), merged at composite"

    def fragment_template(self) -> str:
        """Insertion into the list picked by tie-id parity."""
        return "abuffer/insert_two_lists.glsl.j2"

    def resolve_template(self) -> str:
        """Front-to-back merge of both lists."""
        return "abuffer/resolve_two_lists.glsl.j2"

    def extra_memory(self) -> dict:
        """Both lists' heads."""
        return {"abuffer_heads": 2 * self._pixels * self.link_bytes}


class PreSortCS(ABufferVariant):
    """PreSortCS: sorted insertion inside a per-pixel critical section (interlock or spin lock)."""

    id = "presort_cs"
    early_termination = False
    summary = "sorted insertion in a per-pixel critical section (fragment shader interlock or spin lock)"
    SETTINGS = {
        **PreSortLF.SETTINGS,
        "lock": LOCK_SETTING,
        "max_spin": Setting(
            (int,), 65536, "lock attempts before a fragment gives up (counted, reported)", check=positive
        ),
    }

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
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
        self.lock = resolve_lock(self.id, lock, caps)
        self._use_32bit_links()  # the critical section orders the list: no 64-bit atomics needed
        self.extra_slots = 1 if self.lock == "spin" else 0  # one lock word per pixel

    def compute_raster_refusal(self) -> str | None:
        """The fragment shader interlock has no compute counterpart; the spin lock has."""
        if self.lock == "interlock":
            return "its critical section is the fragment shader interlock (set lock: spin)"
        return super().compute_raster_refusal()

    def fragment_template(self) -> str:
        """Locked sorted insertion."""
        return "abuffer/insert_critical.glsl.j2"

    def resolve_template(self) -> str:
        """The lists are sorted by (depth, tie): PreSortLF's walk."""
        return "abuffer/resolve_sorted.glsl.j2"

    def template_vars(self) -> dict:
        """32-bit lists, the lock kind and its bound."""
        return {
            **super().template_vars(),
            "ab_lock": self.lock,
            "max_spin": int(self.settings["max_spin"]),
            "fragment_interlock": self.lock == "interlock",
        }

    def extensions(self) -> str:
        """Fragment shader interlock where it is the critical section."""
        return super().extensions() + (_INTERLOCK_EXT if self.lock == "interlock" else "")

    def finish(self, frame) -> bool:
        """Counters, plus which critical section ran."""
        again = super().finish(frame)
        frame.stats["critical_section"] = self.lock
        return again

    def extra_memory(self) -> dict:
        """The spin locks."""
        return {"abuffer_locks": self._pixels * 4} if self.lock == "spin" else {}


class PreSortCSET(PreSortCS):
    """PreSortCS*: the critical-section insertion with early termination."""

    id = "presort_cs_et"
    early_termination = True
    summary = "sorted insertion in a per-pixel critical section, with early termination"


class _PostBase(ABufferVariant):
    """Unsorted gathering (head swap); the composite sorts. Truncation is read after the composite."""

    id = ""
    early_termination = False  # nothing is sorted while gathering, so nothing can be known hidden

    def __init__(self, settings, caps):
        super().__init__(settings, caps)
        self._use_32bit_links()  # one 32-bit atomicExchange per fragment

    def fragment_template(self) -> str:
        """Head-swap gathering."""
        return "abuffer/insert_unsorted.glsl.j2"

    def after_composite(self, frame) -> None:
        """Fragments the resolve left out (fixed array full, or walk bound) into stats and warnings."""
        frame.ctx.memory_barrier()
        if frame.late_counters:  # the previous frame's counts (read in finish), this frame's set aside
            super().after_composite(frame)
            c = self.read_counters()
        else:
            c = self.read_counters(fresh=True)  # the composite counted after the geometry read
        fr = frame.stats.setdefault("fragments", {})
        fr["truncated"], fr["truncated_pixels"] = c["truncated"], c["truncated_pixels"]
        if c["truncated"]:
            frame.stats.setdefault("warnings", []).append(self._truncation_warning(c))

    def _truncation_warning(self, c: dict) -> str:
        return (
            f"composite truncated {c['truncated']} fragments in {c['truncated_pixels']} pixels "
            f"(list walk bound max_steps={self.settings['max_steps']})"
        )


class PostSort(_PostBase):
    """PostSort: unsorted per-pixel lists, sorted in a fixed local array (the k nearest kept)."""

    id = "post_sort"
    summary = "unsorted per-pixel lists sorted at composite in a fixed local array (k nearest kept)"
    SETTINGS = {
        **PreSortLF.SETTINGS,
        "max_fragments": Setting(
            (int,),
            32,
            "local array size of the composite sort; farther fragments "
            "of deeper pixels are truncated (counted, reported)",
            check=_array_size,
        ),
    }

    def resolve_template(self) -> str:
        """Fixed-array sort."""
        return "abuffer/resolve_post_sort.glsl.j2"

    def template_vars(self) -> dict:
        """32-bit lists and the array size."""
        return {**super().template_vars(), "max_fragments": int(self.settings["max_fragments"])}

    def _truncation_warning(self, c: dict) -> str:
        return (
            f"post_sort truncated {c['truncated']} fragments in {c['truncated_pixels']} pixels deeper than "
            f"max_fragments={self.settings['max_fragments']} (the nearest were kept); raise max_fragments"
        )


class PostMerge16(_PostBase):
    """PostMerge16: unsorted per-pixel lists, exact order for any depth by rounds of 16 at composite."""

    id = "post_merge16"
    chunk = 16
    summary = "unsorted per-pixel lists ordered at composite in rounds of 16 nearest (no fixed limit)"

    def resolve_template(self) -> str:
        """Rounds of 16."""
        return "abuffer/resolve_post_merge.glsl.j2"

    def template_vars(self) -> dict:
        """32-bit lists and the round size."""
        return {**super().template_vars(), "chunk": self.chunk}
