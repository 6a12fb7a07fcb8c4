"""`transparency: {method: auto}`: the fastest exact method for the device, from a small measured table.

Which exact method is fastest depends on the device more than on anything else guaca knows
before a frame: on an NVIDIA GPU the sorted lock-free A-buffer with early termination is the
fastest or within 6 % on every scene of Table 1, on llvmpipe (Mesa's CPU rasterizer) the
methods lie closer together and paged lists lead by a little. The
tables below hold measured frame times (ms) per scene and method; `choose` ranks the methods of
the device's table by the geometric mean over its scenes of each time relative to the scene's
fastest, and takes the first the device can run at the frame's samples per pixel. How each
table was measured, and when, is in docs/methods.md ("method: auto").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..registry import AUTO, AUTO_CANDIDATES, METHODS


@dataclass(frozen=True)
class DeviceTable:
    """Measured frame times of exact methods on one kind of device."""

    name: str  # what the device is called in the stats
    renderer_keys: tuple[str, ...]  # lower-case substrings of GL_RENDERER or GL_VENDOR that select this table
    measured: str  # how: device, frame size, timer (docs/methods.md gives the command and the date)
    ms: dict[str, dict[str, float]]  # scene -> method id -> ms per frame

    def ranking(self) -> list[tuple[str, float]]:
        """(method, geometric mean of ms / the scene's fastest ms), fastest first; methods of every scene only."""
        methods = set.intersection(*(set(row) for row in self.ms.values()))
        score = {
            m: math.exp(sum(math.log(row[m] / min(row.values())) for row in self.ms.values()) / len(self.ms))
            for m in methods
        }
        return sorted(score.items(), key=lambda kv: (kv[1], kv[0]))


# NVIDIA H100 (PCIe), 1024², GPU timer queries, per-pass sums of the median frame: Table 1
# (benchmarks/results/h100/paper_table/paper_table.json, `raster: auto`).
NVIDIA = DeviceTable(
    "nvidia",
    ("nvidia",),
    "NVIDIA H100, 1024x1024, GPU time (Table 1, benchmarks/results/h100/paper_table)",
    {
        "dragons": {
            "presort_lf_et": 1.843,
            "presort_lf": 1.964,
            "presort_lf_merge2_et": 1.813,
            "presort_cs_et": 2.674,
            "presort_cs": 2.762,
            "post_sort": 1.959,
            "post_merge16": 1.919,
            "multilayer_depth_peeling": 34.52,
        },
        "hairball_v1": {
            "presort_lf_et": 3.142,
            "presort_lf": 7.21,
            "presort_lf_merge2_et": 3.497,
            "presort_cs_et": 4.954,
            "presort_cs": 32.181,
            "post_sort": 5.635,
            "post_merge16": 8.013,
            "multilayer_depth_peeling": 93.749,
        },
        "hairball_v2": {
            "presort_lf_et": 11.225,
            "presort_lf": 20.186,
            "presort_lf_merge2_et": 18.652,
            "presort_cs_et": 14.298,
            "presort_cs": 91.653,
            "post_sort": 35.84,
            "post_merge16": 116.275,
            "multilayer_depth_peeling": 165.387,
        },
        "sponza_dabrovic_v1": {
            "presort_lf_et": 1.148,
            "presort_lf": 1.18,
            "presort_lf_merge2_et": 1.083,
            "presort_cs_et": 1.629,
            "presort_cs": 1.721,
            "post_sort": 1.2,
            "post_merge16": 1.177,
            "multilayer_depth_peeling": 15.892,
        },
        "sponza_dabrovic_v2": {
            "presort_lf_et": 1.297,
            "presort_lf": 1.358,
            "presort_lf_merge2_et": 1.277,
            "presort_cs_et": 1.835,
            "presort_cs": 1.97,
            "post_sort": 1.488,
            "post_merge16": 1.495,
            "multilayer_depth_peeling": 19.537,
        },
    },
)

# llvmpipe (Mesa 22.3, LLVM 15, 2 cores), the default pipeline, CPU time of the process per frame (all of
# llvmpipe's threads; the machine was shared, so wall time varied more), median of 11 frames at 256²
# (mean of two runs) and of 7 at 1024x768; the exact methods that rank within 2x on every scene
# (the peeling methods took 1.3-5x longer, but for hybrid peeling on 12 planar layers).
LLVMPIPE = DeviceTable(
    "llvmpipe",
    ("llvmpipe",),
    "llvmpipe (2 cores), CPU ms per frame, docs/methods.md (2026-11-27)",
    {
        "demo 256x256": {
            "presort_lf_et": 30.7,
            "presort_lf": 31.1,
            "presort_lf_merge2_et": 32.9,
            "presort_cs_et": 33.8,
            "post_sort": 28.6,
            "post_merge16": 29.0,
            "paged_ll": 29.6,
            "sbuffer": 30.1,
            "dfb": 32.5,
        },
        "layered_quads(12) 256x256": {
            "presort_lf_et": 34.8,
            "presort_lf": 35.6,
            "presort_lf_merge2_et": 35.0,
            "presort_cs_et": 39.5,
            "post_sort": 32.5,
            "post_merge16": 32.0,
            "paged_ll": 30.6,
            "sbuffer": 34.8,
            "dfb": 34.4,
        },
        "layered_quads(32) 256x256": {
            "presort_lf_et": 58.5,
            "presort_lf": 105.3,
            "presort_lf_merge2_et": 63.6,
            "presort_cs_et": 66.4,
            "post_sort": 63.5,
            "post_merge16": 64.8,
            "paged_ll": 61.3,
            "sbuffer": 68.2,
            "dfb": 67.7,
        },
        "interpenetrating 256x256": {
            "presort_lf_et": 15.7,
            "presort_lf": 16.1,
            "presort_lf_merge2_et": 17.3,
            "presort_cs_et": 18.1,
            "post_sort": 17.4,
            "post_merge16": 17.6,
            "paged_ll": 16.3,
            "sbuffer": 17.4,
            "dfb": 20.2,
        },
        "demo 1024x768": {
            "presort_lf_et": 253.8,
            "presort_lf": 253.4,
            "presort_lf_merge2_et": 268.3,
            "presort_cs_et": 268.5,
            "post_sort": 243.5,
            "post_merge16": 248.6,
            "paged_ll": 239.2,
            "sbuffer": 243.2,
            "dfb": 271.3,
        },
        "layered_quads(32) 1024x768": {
            "presort_lf_et": 541.2,
            "presort_lf": 956.2,
            "presort_lf_merge2_et": 611.3,
            "presort_cs_et": 629.5,
            "post_sort": 669.0,
            "post_merge16": 635.7,
            "paged_ll": 575.6,
            "sbuffer": 611.6,
            "dfb": 632.9,
        },
    },
)

TABLES = (LLVMPIPE, NVIDIA)
FALLBACK = NVIDIA  # a GPU without measurements of its own: the GPU's table


def table_for(caps) -> tuple[DeviceTable, bool]:
    """The table of the device `caps` describes, and whether it was measured there (False: the fallback)."""
    name = f"{caps.gl_renderer} {caps.vendor}".lower()
    for table in TABLES:
        if any(key in name for key in table.renderer_keys):
            return table, True
    return FALLBACK, False


def candidates() -> list[str]:
    """Every method some table ranks (what `auto` may pick), in id order."""
    return sorted({m for table in TABLES for row in table.ms.values() for m in row})


def choose(caps, samples: int = 1) -> tuple[str, str]:
    """(method id, why): the fastest exact method of the device's table it runs at `samples` per pixel."""
    table, measured = table_for(caps)
    ranking = table.ranking()
    for i, (mid, score) in enumerate(ranking):
        spec = METHODS.get(mid)
        if spec.unsupported_reason(caps) is not None or (samples > 1 and not spec.supports_antialiasing):
            continue
        where = table.name if measured else f"{caps.gl_renderer} (not measured; the {table.name} table)"
        faster = [m for m, _ in ranking[:i]]
        if faster:
            at = f" at {samples} samples" if samples > 1 else ""
            where += f" that runs here{at} ({', '.join(faster)} do not)"
        others = ", ".join(f"{m} {s:.2f}" for m, s in ranking[:4] if m != mid)
        why = (
            f"fastest exact method measured on {where}: {score:.2f}x the fastest per scene (geometric mean "
            f"over {len(table.ms)} scenes; {others}); {table.measured}"
        )
        return mid, why
    raise LookupError(f"no method of the {table.name} table runs on {caps.gl_renderer}")


AUTO_CANDIDATES.update(candidates())
__all__ = ["AUTO", "DeviceTable", "TABLES", "candidates", "choose", "table_for"]
