"""Where each method breaks: error against the float64 CPU reference as depth complexity grows.

Scene: guaca_py.reference's layered quads (shuffled submission, one opaque quad mid-stack), rendered
through pipelines/exact.yaml; error on non-edge pixels in 1/255 (RMSE and max). Each configuration
shows one limit: approximate methods at their defaults, and exact methods with a deliberately
small bound (post_sort's local array, a peeling pass cap, a fixed A-buffer pool, an
early-termination threshold) whose counters must explain the error. Accuracy does not depend on
the device, so this runs anywhere (llvmpipe included); benchmarks/breaking_points.py writes it.
"""

from __future__ import annotations

from collections.abc import Callable

import moderngl

from ..errors import GuacaError
from ..reference import compare, layered_quads_scene, reference_of
from ..renderer import Renderer

# (label, method id, settings, counter that reports the limit being hit)
CONFIGS = [
    ("unsorted_blend", "unsorted_blend", {}, None),
    ("object_sorted_blend", "object_sorted_blend", {}, None),
    ("weighted_blended", "weighted_blended", {}, None),
    ("stochastic S=8", "stochastic", {"samples": 8}, None),
    ("stochastic S=32", "stochastic", {"samples": 32}, None),
    ("kbuffer k=4 merge", "kbuffer", {"k": 4, "overflow": "merge"}, "merged"),
    ("kbuffer k=8 merge", "kbuffer", {"k": 8, "overflow": "merge"}, "merged"),
    ("kbuffer k=8 drop", "kbuffer", {"k": 8, "overflow": "drop"}, "dropped"),
    ("post_sort max_fragments=8", "post_sort", {"max_fragments": 8}, "truncated"),
    ("depth_peeling max_passes=6", "depth_peeling", {"max_passes": 6}, "truncated"),
    ("presort_lf_et threshold=0.9", "presort_lf_et", {"threshold": 0.9}, "early_termination_culled"),
    ("presort_lf budget 0.05 MB", "presort_lf", {"budget_mb": 0.05}, "overflow"),
    ("presort_lf (exact)", "presort_lf", {}, None),
]


def run(ctx: moderngl.Context, size: int, layer_counts: list[int], progress: Callable[[str], None] = print) -> dict:
    """Render every configuration at every depth complexity on context `ctx`; rows of errors and counters."""
    rows = []
    renderers = {}
    for n in layer_counts:
        scene = layered_quads_scene(n_layers=n, order="shuffled", seed=5)
        ref, mask, layers = reference_of(scene, size, size)
        for label, mid, settings, counter in CONFIGS:
            row = {"config": label, "method": mid, "layers": n, "max_depth_complexity": int(layers.max())}
            try:
                if label not in renderers:
                    renderers[label] = Renderer("exact", ctx=ctx, method=mid, method_overrides=settings)
                frame = renderers[label].render(scene, size, size)
                err = compare(frame.image, ref, mask)
                frags = frame.stats.get("fragments", {})
                row.update(
                    rmse_255=err["rmse_255"],
                    max_255=err["max_abs_255"],
                    counter=counter,
                    counted=int(frags.get(counter, 0)) if counter else None,
                    warnings=frame.stats.get("warnings", []),
                )
            except GuacaError as exc:
                row["unavailable"] = str(exc)
            rows.append(row)
        progress(f"{n:>3} layers done")
    for r in renderers.values():
        r.release()
    return {
        "meta": {
            "device": ctx.info["GL_RENDERER"],
            "size": size,
            "layers": layer_counts,
            "scene": "layered quads, shuffled, seed 5",
            "unit": "1/255, non-edge pixels",
        },
        "rows": rows,
    }


def table(data: dict) -> str:
    """Markdown: RMSE / max per configuration and depth complexity, with the limit counter."""
    meta, rows = data["meta"], data["rows"]
    ns = meta["layers"]
    out = [
        f"Error vs float64 reference (RMSE / max, {meta['unit']}), {meta['size']}² px, {meta['scene']}, "
        f"device {meta['device']}. In brackets: the counter that reports the limit (fragments).",
        "",
        "| config | " + " | ".join(f"{n} layers" for n in ns) + " |",
        "|---|" + "---|" * len(ns),
    ]
    for label, *_ in CONFIGS:
        cells = []
        for n in ns:
            r = next(r for r in rows if r["config"] == label and r["layers"] == n)
            if "unavailable" in r:
                cells.append("n/a")
                continue
            c = f"{r['rmse_255']:.2f} / {r['max_255']:.0f}"
            if r["counter"]:
                c += f" [{r['counter']} {r['counted']}]"
            cells.append(c)
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"
