"""`antialiasing: auto`: 4 coverage samples or supersample 2, chosen per frame from the previous frame.

The first frame renders with 4 coverage samples. Every frame records what the next one decides
from: the mean projected area of its transparent triangles in output pixels (the sampled estimate
`raster: auto` uses, guaca_py/raster/choice.py) and its stored fragments. The cost model, relative
to the same frame at 1 sample (docs/antialiasing.md, "antialiasing: auto"):

* 4 coverage samples: a fixed part (multisampled G-buffer, per-sample composite) plus the edge
  fragments. A triangle of area `a` px² makes about `1 + EDGE / sqrt(a)` times its 1-sample
  fragments (every pixel that any sample of it covers), each walking lists grown alike:
  `COVERAGE_FIXED + COVERAGE_EDGE * EDGE / sqrt(a)`, so small triangles make it expensive.
* supersample 2: four times the pixels and fragments, but not the per-triangle work (vertex,
  setup): `1 + 3 * a / (a + TRIANGLE_FRAGMENTS)`, the share of the frame that grows with the
  fragments being `a / (a + TRIANGLE_FRAGMENTS)` (a triangle of area `a` makes about `a` fragments).

The stated edge quality: an edge error no higher than supersample 2's. 4 coverage samples shade a
triangle once per pixel (at the centroid of the samples it covers), supersampling once per sample;
where the normals turn fast across the screen (NORMAL_TURN_MAX radians per pixel, median over the
sampled triangles: hair and fibre seen from afar), the shading varies within a pixel and 4 samples
miss it, so supersample 2 is taken there whatever it costs (hairball_v1 at 1024²: 0.88 rad/px, edge
RMSE 5.39 with 4 samples, 3.54 with supersample 2, 4.45 even with 8 samples), with the HYSTERESIS
of the costs around the line.

Otherwise supersample 2 is chosen where its estimate is lower (by HYSTERESIS when the previous frame
ran the other mode, so a camera near the crossing does not switch every frame). Either way it needs
the 1-sample fragments, four times over, to fit the method's node pool at four times the pixels (the
pool's own sizing by the device's storage rule, TransparencyMethod.pool_fragments); 4 samples otherwise, and
always for a method that cannot carry coverage masks (supersample 2 then) or a frame without
transparent draws.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from .pipeline.device import Antialiasing
from .raster.choice import projected_shape

# The constants come from the H100 at 1024² (presort_lf_et, raster: auto; benchmarks/results/h100/
# aa_cost/ and accuracy_scenes/; docs/antialiasing.md): 4 samples against 1 stored 3.08x the fragments
# on the dragons (mean triangle area 0.31 px²), 1.13x / 1.11x on Sponza v1 / v2 (92 / 158 px²), 1.79x /
# 1.15x on hairball_v1 / v2 (5.2 / 34.6 px²); their frames took 3.19x, 1.57x, 1.51x, 2.64x and 1.92x;
# the dragons' 2048² frame (supersample 2's) took 2.10x the 1024² one. Checked against the chart of
# benchmarks/accuracy_scenes.py --aa-chart (benchmarks/results/h100/accuracy_scenes/aa_chart.md): the
# rule took the cheaper mode on all five scenes (supersample 2 on the dragons: 3.85 ms against 5.98;
# 4 samples on Sponza v1 / v2 and the hairballs, 3-3.5x cheaper there than supersample 2).
EDGE = 1.25  # fragment growth at 4 samples: 1 + EDGE / sqrt(area px²) (fit: 1.15 dragons ... 1.38 Sponza v2)
COVERAGE_FIXED = 1.46  # the 4-sample frame's cost where the triangles are large (Sponza: 1.51-1.57x)
COVERAGE_EDGE = 0.83  # cost per unit of extra fragment growth (the dragons: 3.19x at 3.08x the fragments)
TRIANGLE_FRAGMENTS = 0.48  # a triangle's fixed work in fragments' worth (the dragons' 2048² frame: 2.10x)
# Edge quality (the H100 chart at 1024², benchmarks/results/h100/accuracy_scenes/aa_chart.md, and the
# median normal turn per pixel of each scene's sampled triangles): 4 samples beat supersample 2's edge
# RMSE on Sponza v1 / v2 (0.34 / 0.33 rad/px) and the hairball_v2 view (0.41), came within 8 % on the
# dragons (0.17; 1.53 against 1.42) and fell short on hairball_v1 (0.88 rad/px: 5.39 against 3.54).
NORMAL_TURN_MAX = 0.6
HYSTERESIS = 0.1  # leave the previous frame's mode only for an estimate this much lower
SUPERSAMPLE = 2
COVERAGE_SAMPLES = 4


def coverage_cost(area_px: float) -> float:
    """Estimated cost of 4 coverage samples, relative to 1 sample, for triangles of mean area `area_px` (px²)."""
    return COVERAGE_FIXED + COVERAGE_EDGE * EDGE / math.sqrt(max(area_px, 1e-6))


def supersample_cost(area_px: float) -> float:
    """Estimated cost of supersample 2, relative to 1 sample, for triangles of mean area `area_px` (output px²)."""
    share = area_px / (area_px + TRIANGLE_FRAGMENTS)  # the part of the frame that grows with the fragments
    return 1.0 + (SUPERSAMPLE**2 - 1) * share


def label(aa: Antialiasing) -> str:
    """How a mode is named in the stats: 'samples 4' or 'supersample 2'."""
    return f"supersample {aa.supersample}" if aa.supersample > 1 else f"samples {aa.asked}"


def choose(
    measured: dict | None,
    previous: str | None,
    coverage_possible: str | None,
    pool_fragments: Callable[[int], int] | None,
) -> tuple[str, str]:
    """('samples' or 'supersample', why) for a frame, from the previous frame's measurements.

    `measured`: measure()'s dict (mean triangle area, normal turn, 1-sample fragments, output pixels, transparent
    draws) or None before the first frame;
    `previous`: the mode the previous frame ran; `coverage_possible`: None, or why 4 samples cannot run;
    `pool_fragments`: the method's pool rule, rendered pixels -> the most fragments it stores (TransparencyMethod.pool_fragments).
    """
    if coverage_possible is not None:
        return "supersample", coverage_possible
    if measured is None:
        return "samples", "the first frame renders with 4 samples"
    if measured.get("transparent_draws", 1) == 0:
        return "samples", "no transparent draws: 4 samples cost only the multisampled G-buffer"
    area = measured["mean_triangle_area_px"]
    cov, ss = coverage_cost(area), supersample_cost(area)
    costs = f"mean triangle area {area:.3g} px²: estimated cost x{cov:.2f} with 4 samples, x{ss:.2f} with supersample 2"
    turn = measured.get("normal_turn_per_px", 0.0)
    if pool_fragments is not None:
        need = SUPERSAMPLE**2 * measured["fragments_1x"]
        room = pool_fragments(SUPERSAMPLE**2 * measured["output_pixels"])
        if need > room:
            return (
                "samples",
                f"{costs}; supersample 2 would store {need:,} fragments, over the {room:,} its pool holds "
                "within the device's buffers",
            )
    # with the same hysteresis as the costs: a camera near the line does not switch every frame
    line = NORMAL_TURN_MAX * {"samples": 1.0 + HYSTERESIS, "supersample": 1.0 - HYSTERESIS}.get(previous, 1.0)
    if turn > line:
        return (
            "supersample",
            f"normals turn {turn:.2f} rad per pixel (> {line:.2f}): shading varies within a pixel, "
            f"4 samples (one shade per pixel) would miss the edge quality of supersample 2; {costs}",
        )
    margin = 1.0 - HYSTERESIS if previous == "samples" else 1.0 + HYSTERESIS
    if ss < cov * margin:
        return "supersample", costs
    return "samples", costs


def fragment_growth(aa: Antialiasing, area_px: float) -> float:
    """Fragments of a frame in mode `aa` per fragment of the same frame at 1 sample (the model's estimate)."""
    if aa.supersample > 1:
        return float(aa.supersample**2)
    if aa.samples > 1:
        return min(float(aa.samples), 1.0 + EDGE / math.sqrt(max(area_px, 1e-6)))
    return 1.0


def measure(frame) -> dict:
    """What the next frame decides from: the transparent triangles' mean projected area in output pixels and
    how fast their normals turn (radians per output pixel), both weighted by triangle count, and the stored
    fragments as at 1 sample (divided by the mode's growth)."""
    w, h = frame.output_size
    k = frame.supersample  # measured at the rendered size, as raster: auto measures it (one cache entry)
    vp = frame.projection @ frame.view
    total = turns = weight = 0.0
    for d in frame.transparent_draws:
        area, turn = projected_shape(d.mesh, d.world, vp, frame.width, frame.height)
        if area > 0:  # on screen
            total += area / (k * k) * d.mesh.triangle_count
            turns += turn * k * d.mesh.triangle_count
            weight += d.mesh.triangle_count
    area = total / weight if weight else 0.0
    one = frame.stats.get("fragments", {}).get("stored", 0) / fragment_growth(frame.device.antialiasing, area)
    return {
        "transparent_draws": len(frame.transparent_draws),
        "mean_triangle_area_px": round(area, 4),
        "normal_turn_per_px": round(turns / weight if weight else 0.0, 4),
        "fragments_1x": int(one),
        "fragments_per_pixel_1x": round(one / (w * h), 3),
        "output_pixels": w * h,
    }


class AutoAntialiasing:
    """Per frame, which of two modes the Renderer's device renders with, and the report of why."""

    def __init__(self, coverage: Antialiasing | None, why_not_coverage: str | None = None):
        self.coverage = coverage  # 4 samples as the device renders them; None where it has no multisampling
        self.supersampled = Antialiasing(supersample=SUPERSAMPLE)
        self.why_not_coverage = why_not_coverage if coverage is not None else "the device renders 1 sample per pixel"
        self.measured: dict | None = None  # the previous frame's
        self.mode: str | None = None  # the previous frame's: 'samples' or 'supersample'

    def method_changed(self, method_cls) -> None:
        """The transparency method changed: 4 samples only where it carries coverage masks."""
        if self.coverage is None:
            return
        self.why_not_coverage = (
            None
            if method_cls.supports_antialiasing
            else f"method '{method_cls.id}' carries no coverage masks ({method_cls.antialiasing_refusal})"
        )

    def choose(self, pool_fragments: Callable[[int], int] | None) -> tuple[Antialiasing, dict]:
        """The mode of the next frame and its report for `stats['antialiasing']['auto']`."""
        mode, why = choose(self.measured, self.mode, self.why_not_coverage, pool_fragments)
        self.mode = mode
        aa = self.coverage if mode == "samples" else self.supersampled
        report = {"chose": label(aa), "why": why}
        if self.measured is not None:
            report["previous_frame"] = dict(self.measured)
        return aa, report

    def record(self, frame) -> None:
        """Measure the frame just rendered, for the next one."""
        self.measured = measure(frame)


__all__ = [
    "AutoAntialiasing",
    "choose",
    "coverage_cost",
    "supersample_cost",
    "measure",
    "fragment_growth",
]
