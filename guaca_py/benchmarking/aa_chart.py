"""The anti-aliasing chart a user chooses from: each way to anti-alias, its edge error and its time, per scene.

`benchmarks/accuracy_scenes.py --aa-chart` renders, per scene, the default exact method at 1 sample
(with and without FXAA), at 2/4/8 coverage samples, supersampled 2x and 3x, and with
`antialiasing: auto`, against the same 8x8 reference as the method table; this module holds those
configurations, how a frame's linear colour is read (the FXAA row's output is sRGB 8-bit), and the
table and the chart (error against frame time, one panel per scene).
"""

from __future__ import annotations

import numpy as np

from ..antialiasing import with_settings, with_supersample
from ..pipeline.config import PipelineConfig
from ..reference import linear_pipeline
from .charts import plain_log_axis, time_label
from .harness import timer_of, timer_sentence
from .rows import flip_cell, stored_cell

AA_METHOD = "presort_lf_et"  # the exact default
SAMPLES = (2, 4, 8)
SUPERSAMPLE = (2, 3)


def fxaa_pipeline() -> PipelineConfig:
    """linear_pipeline's frame at 1 sample, then tone mapping that only clips and encodes sRGB, then FXAA (as a
    display image gets it); the row's linear colour is decoded from its sRGB 8-bit output."""
    return linear_pipeline(1, post=("{tone_mapping: {operator: clamp, exposure: 1.0, srgb: true}}", "fxaa"))


def configs(samples=SAMPLES, supersample=SUPERSAMPLE) -> list[tuple[dict, PipelineConfig]]:
    """(row, pipeline) of each way to anti-alias, cheapest first; `mode` names it in the chart."""
    base = linear_pipeline(1)
    out = [
        ({"label": "1 sample", "mode": "none", "samples": 1}, base),
        ({"label": "1 sample + FXAA", "mode": "fxaa", "samples": 1}, fxaa_pipeline()),
    ]
    out += [({"label": f"{n} samples", "mode": "samples", "samples": n}, linear_pipeline(n)) for n in samples]
    out += [
        (
            {"label": f"supersample {k}", "mode": "supersample", "samples": 1, "supersample": k},
            with_supersample(base, k, "aa_chart"),
        )
        for k in supersample
    ]
    out.append(({"label": "auto", "mode": "auto", "samples": 1}, with_settings(base, "auto", "aa_chart")))
    for row, _ in out:
        row.update(method=AA_METHOD, exact=True, settings={})
    return out


def linear_of(frame) -> np.ndarray:
    """A frame's linear colour: its float output, or its sRGB 8-bit image decoded (the FXAA row)."""
    if frame.linear is not None:
        return frame.linear
    c = frame.image.astype(np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def chosen(stats: dict) -> str | None:
    """What `antialiasing: auto` chose in a frame, or None for the other rows."""
    return (stats.get("antialiasing", {}).get("auto") or {}).get("chose")


def markdown(recs: list[dict]) -> str:
    """One table of every scene's rows: time, edge error, FLIP, stored fragments, and the command of each."""
    top = "# Anti-aliasing: edge error against frame time, per scene"
    out = [
        top,
        "",
        f"`{AA_METHOD}` (exact) at 1 sample with and without FXAA, at 2/4/8 coverage samples, supersampled 2x and "
        "3x, and `antialiasing: auto`; error in 1/255 of the linear output clipped to [0, 1] against "
        f"`presort_lf` at 8x8 the resolution, box filtered; edge pixels: those whose 8x8 sub-pixels span > 0.05. "
        "The FXAA row is read from its sRGB 8-bit output (tone mapping: clamp, no exposure), so it also "
        "carries 8-bit quantisation. Time: median frame (sum of pass times). "
        + timer_sentence(timer_of([r for rec in recs for r in rec["rows"]])),
        "",
        "![edge error against frame time](aa_chart.png)",
        "",
        "| scene | configuration | samples | frame ms | edge RMSE | RMSE | FLIP | stored | rendered | auto chose |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rec in recs:
        for r in rec["rows"]:
            if "skipped" in r:
                out.append(f"| {rec['scene']} | {r['label']} | | skipped: {r['skipped']} | | | | | | |")
                continue
            fl, stored = flip_cell(r), stored_cell(r)
            size = "x".join(map(str, r.get("render_resolution") or [rec["size"]] * 2))
            out.append(
                f"| {rec['scene']} | {r['label']} | {r['samples']} | {r['ms']:.3f} | {r['edge_rmse_255']:.2f} | "
                f"{r['rmse_255']:.2f} | "
                f"{fl} | {stored} | {size} | {r.get('auto_chose') or ''} |"
            )
    out += ["", "Commands:", ""] + [f"- {rec['scene']}: `{rec['command']}` ({rec['device']})" for rec in recs]
    return "\n".join(out) + "\n"


MARKERS = {"none": ("o", "tab:gray"), "fxaa": ("D", "tab:purple"), "samples": ("s", "tab:green")}
MARKERS.update(supersample=("^", "tab:blue"), auto=("*", "tab:red"))


def chart(recs: list[dict], plt):
    """Edge RMSE (top) and, where measured, FLIP (bottom) against frame time: one panel per scene."""
    flip = any(r.get("flip") is not None for rec in recs for r in rec["rows"] if "skipped" not in r)
    keys = [("edge_rmse_255", "edge RMSE (1/255)")] + ([("flip", "mean FLIP")] if flip else [])
    n = max(1, len(recs))
    fig, axes = plt.subplots(len(keys), n, figsize=(max(8.0, 4.2 * n), 3.8 * len(keys) + 0.4), squeeze=False)
    for col, rec in enumerate(recs):
        rows = [r for r in rec["rows"] if "skipped" not in r]
        for (key, name), ax in zip(keys, axes[:, col]):
            for mode in ("samples", "supersample"):  # each family joined by a line, in its order
                line = [r for r in rows if r["mode"] == mode]
                ax.plot([r["ms"] for r in line], [r[key] for r in line], "-", color=MARKERS[mode][1], lw=1, zorder=1)
            for i, r in enumerate(rows):
                marker, color = MARKERS[r["mode"]]
                ax.scatter(r["ms"], r[key], marker=marker, color=color, s=70 if r["mode"] == "auto" else 30, zorder=2)
                label = r["label"] + (f" ({r['auto_chose']})" if r.get("auto_chose") else "")
                ax.annotate(
                    label, (r["ms"], r[key]), fontsize=6, xytext=(4, (-10, 4, 12)[i % 3]), textcoords="offset points"
                )
            ax.set_xscale("log")
            plain_log_axis(ax.xaxis)
            ax.set_xlabel(time_label(timer_of(rows), "frame time, ms"))
            ax.set_ylabel(name)
            ax.set_title(f"{rec['scene']} ({rec['size']}²)", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(
        f"Anti-aliasing ({AA_METHOD}): error against the 8x8 reference and frame time\n"
        "grey: 1 sample, purple: FXAA, green: coverage samples, blue: supersampling, red star: auto",
        fontsize=9,
    )
    fig.tight_layout()
    return fig
