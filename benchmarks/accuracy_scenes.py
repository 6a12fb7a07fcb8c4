"""Speed against error on real scenes: every method, and the exact default at 1/2/4/8 samples.

Usage: python benchmarks/accuracy_scenes.py [--out DIR] [--scenes .scenes] [--scene-names NAME ...] [--size 1024]
                                           [--ref-k 8] [--tile 2048] [--frames 5] [--warmup 2] [--warmup-s 1.5]
                                           [--budget-s 3] [--scene-budget-s S] [--methods ID ...]
                                           [--samples 1 2 4 8] [--flip-workers N] [--aa-chart] [--replot]
Each scene renders through guaca_py.reference.linear_pipeline: light culling as in the default
pipeline, no tone mapping or FXAA (linear output), threshold 0.999 for every method, so exact
methods differ from the reference by their aliasing alone. Reference (guaca_py.reference.exact_reference):
presort_lf (exact, no early termination, hardware rasterizer) at --ref-k x the resolution, in tiles of
at most --tile px, box filtered (a tile whose fragments overflow the A-buffer pool is reported: use
smaller tiles). Error (linear, clipped to [0, 1], in 1/255): RMSE over all pixels, RMSE over edge
pixels (their k x k sub-pixels span > 0.05: silhouettes, boundaries, intersections), mean FLIP
(sRGB-encoded, when flip-evaluator is installed; in --flip-workers processes while the GPU renders on).
Time: median of --frames per-pass timer sums after --warmup frames and --warmup-s seconds (GPU timers
only: wall time on software rasterizers, which get no time-based warm-up), measured again (up to 2
times) while the sampled SM clock was below its maximum, and marked if it still was. A configuration
whose first frame exceeds --budget-s is timed on one frame; once a scene has run for --scene-budget-s
its remaining configurations are skipped (the sample counts run first; the first always runs).
Writes benchmarks/results/<device>/accuracy_scenes/<scene>/accuracy.{json,md,png} and its README.md.
A reference tile whose fragments overflow the A-buffer pool is rendered again as four tiles (that tile
alone, down to 256 px: reference/supersampled.py), so one command serves scenes of every depth complexity.

--aa-chart: instead of the methods, the ways to anti-alias (guaca_py.benchmarking.aa_chart): presort_lf_et at 1
sample with and without FXAA, at 2/4/8 coverage samples, supersampled 2x and 3x, and antialiasing: auto, each
timed and measured against the same reference; writes accuracy_scenes/aa_chart/<scene>.json, and aa_chart.md
(one table) and aa_chart.png (edge RMSE and FLIP against frame time, one panel per scene) beside them.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from guaca_py import Renderer
from guaca_py.benchmarking import (
    RETRIES,
    Progress,
    Results,
    aa_chart,
    add_reference_args,
    below_max_clock,
    bench_args,
    config_rows,
    max_sm_clock,
    measure_point,
    open_device,
    plain_log_axis,
    ratio_at_full_clock,
    scene_paths,
    time_label,
    timer_of,
    timer_sentence,
    top_clock,
)
from guaca_py.benchmarking.rows import flip_cell, stored_cell
from guaca_py.methods import method_class, method_ids
from guaca_py.reference import edge_pixels, exact_reference, frame_errors, linear_pipeline
from guaca_py.scene.loader import load_scene

AA_METHOD = aa_chart.AA_METHOD  # the exact default, measured at every sample count
REFERENCE_METHOD = "presort_lf"  # exact without early termination


def configs(methods: list[str] | None, samples: list[int]) -> list[tuple[str, str, int, dict]]:
    """(label, method, samples, overrides): the default at each sample count (`raster: auto`: the compute
    rasterizer on a GPU, with coverage masks), the same through the hardware rasterizer at 1 and 4 samples,
    then every other method at 1 sample (a method the device refuses is skipped). The sample counts come
    first: a scene's time budget cuts the method list, not the anti-aliasing result."""
    out = [(f"{AA_METHOD} x{n}", AA_METHOD, n, {}) for n in samples]
    out += [(f"{AA_METHOD} hw x{n}", AA_METHOD, n, {"raster": "hardware"}) for n in (1, 4) if n in samples]
    return out + [(m, m, 1, {}) for m in (methods or method_ids()) if m != AA_METHOD]


def method_configs(ctx, args):
    """(row, make_renderer) of configs(): the exact default at each sample count and rasterizer, then the methods."""

    def renderer(n: int, mid: str, overrides: dict):
        pipeline = linear_pipeline(n)
        return lambda: Renderer(pipeline, ctx=ctx, method=mid, method_overrides=overrides or None)

    return [
        (
            {"label": label, "method": mid, "samples": n, "exact": method_class(mid).exact, "settings": overrides},
            renderer(n, mid, overrides),
        )
        for label, mid, n, overrides in configs(args.methods, args.samples)
    ]


def aa_configs(ctx, args):
    """(row, make_renderer) of the anti-aliasing chart (guaca_py.benchmarking.aa_chart)."""
    return [(row, lambda p=pipeline: Renderer(p, ctx=ctx)) for row, pipeline in aa_chart.configs()]


def reference(ctx, scene, args, progress: Progress, name: str):
    """The scene's supersampled exact reference (a tile that overflowed the pool is rendered again as four)."""
    t0 = time.perf_counter()
    ref = exact_reference(ctx, scene, args.size, args.size, args.ref_k, args.tile, REFERENCE_METHOD)
    progress.note(
        f"{name}: reference {args.ref_k}x ({ref.tiles} tiles of at most {args.tile}²) {time.perf_counter() - t0:.1f} s"
        + (f", OVERFLOW: {ref.overflow} fragments dropped" if ref.overflow else "")
    )
    return ref


def run_scene(ctx, path: Path, args, pool, progress: Progress, make_configs=method_configs) -> dict:
    """Reference, then every configuration of one scene (until --scene-budget-s); the scene's JSON record."""
    t0 = time.perf_counter()
    scene = load_scene(path)
    size = args.size
    ref = reference(ctx, scene, args, progress, path.stem)
    edges = edge_pixels(ref)
    progress.note(f"{path.stem}: edge pixels {edges.mean():.1%}")

    def measure_row(r: Renderer, row: dict) -> None:
        point = measure_point(
            r,
            scene,
            size,
            frames=args.frames,
            warmup=args.warmup,
            warmup_s=args.warmup_s,
            slow_s=args.budget_s,
            share=1.0,  # a row below the maximum clock is marked in the table
        )
        frame = point.last
        row.update(ms=point.total_ms, pass_ms=point.pass_ms, frames=point.frames, timer=point.timer)
        row.update(clock=point.clock, clock_retries=point.clock_retries)
        row["samples"] = frame.stats.get("antialiasing", {}).get("samples", row["samples"])
        row["render_resolution"] = frame.stats.get("render_resolution")
        row["auto_chose"] = aa_chart.chosen(frame.stats)
        row.update(frame_errors(aa_chart.linear_of(frame), ref.image, edges, pool))
        row["fragments"] = frame.stats.get("fragments", {})
        row["raster"] = frame.stats.get("raster", {}).get("why")
        row["memory"] = frame.stats.get("memory", {})
        row["warnings"] = frame.stats.get("warnings", [])

    def report(row: dict) -> None:
        if "skipped" in row:
            progress.step(f"{path.stem} {row['label']}: skipped ({row['skipped']})")
            return
        fl = f"  FLIP {row['flip']:.4f}" if isinstance(row["flip"], float) else ""
        mhz = f"  {row['clock']['sm_clock_mhz_median']} MHz" if row["clock"] else ""
        again = f" ({row['clock_retries']} retries)" if row["clock_retries"] else ""
        progress.step(
            f"{path.stem} {row['label']:28s} {row['ms']:9.3f} ms  RMSE {row['rmse_255']:6.2f}  "
            f"edge {row['edge_rmse_255']:6.2f}{fl}{mhz}{again}"
        )

    rows = config_rows(make_configs(ctx, args), measure_row, report, t0, args.scene_budget_s)
    for row in rows:
        if hasattr(row.get("flip"), "result"):
            row["flip"] = row["flip"].result()
    return {
        "scene": path.stem,
        "file": path.name,
        "size": size,
        "reference": {
            "method": REFERENCE_METHOD,
            "k": args.ref_k,
            "tiles": ref.tiles,
            "tile_px": args.tile,
            "overflow": ref.overflow,
            "edge_tolerance": 0.05,
        },
        "edge_pixels": int(edges.sum()),
        "max_sm_clock_mhz": max_sm_clock(),
        "warmup_s": args.warmup_s,
        "scene_budget_s": args.scene_budget_s,
        "rows": rows,
    }


def is_aa(row: dict) -> bool:
    """A row of the default's sample-count series."""
    return row["label"] in {f"{AA_METHOD} x{n}" for n in (1, 2, 4, 8)}


def clock_line(rec: dict) -> str:
    """The per-scene page's sentence on the SM clock."""
    top = top_clock(rec)
    if top is None:
        return "SM clock: not sampled (no nvidia-smi)."
    mark = "`*` marks frame times whose median clock was below it (or not sampled)."
    return (
        f"SM clock maximum: {top:g} MHz. Each configuration renders for {rec['warmup_s']:g} s before it is timed, "
        f"and is timed again (up to {RETRIES} times) while its median sampled clock is below the maximum; {mark}"
    )


def cost_ratio(one: dict, four: dict, top: float | None) -> str:
    """The frame-time part of the 4-against-1 sentence; no ratio between rows not both at the maximum clock."""
    ratio = ratio_at_full_clock(one, four, top)
    if ratio is None:
        low = [r for r in (one, four) if below_max_clock(r.get("clock"), top)]
        why = ", ".join(f"{r['label']} at {mhz(r)}" for r in low)
        return f"frame time: no ratio, not every row ran at the maximum SM clock of {top:g} MHz ({why})."
    return f"frame time {ratio:.2f}x (target <= 1.6)."


def mhz(row: dict) -> str:
    """A row's median SM clock in words."""
    return f"{row['clock']['sm_clock_mhz_median']:g} MHz" if row.get("clock") else "an unsampled clock"


def markdown(rec: dict) -> str:
    """One scene's table."""
    ref = rec["reference"]
    top = top_clock(rec)
    overflow = ref.get("overflow", 0)
    out = [
        f"# {rec['scene']}: speed against error at {rec['size']}²",
        "",
        f"Device: {rec['device']}. Reference: `{ref['method']}` at {ref['k']}x ({ref['tiles']} tiles), box filtered"
        + (f", NOT EXACT: {overflow} fragments dropped by A-buffer overflow" if overflow else "")
        + f". Edge pixels (sub-pixels span > {ref['edge_tolerance']}): {rec['edge_pixels']}.",
        "Error in 1/255 of the linear output clipped to [0, 1]; time: median frame (sum of pass times). "
        + timer_sentence(timer_of(rec["rows"])),
        clock_line(rec),
        "",
        f"Command: `{rec['command']}`",
        "",
        "![speed against error](accuracy.png)",
        "",
        "| configuration | exact | samples | frame ms | SM MHz | RMSE | edge RMSE | FLIP | node B | stored |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    marked = False
    for r in rec["rows"]:
        if "skipped" in r:
            out.append(f"| {r['label']} | | {r['samples']} | skipped: {r['skipped']} | | | | | | |")
            continue
        fl, stored = flip_cell(r), stored_cell(r)
        node = r["memory"].get("abuffer_node_bytes", "—")
        star = "*" if below_max_clock(r.get("clock"), top) else ""
        marked = marked or bool(star)
        clock = f"{r['clock']['sm_clock_mhz_median']:g}" if r.get("clock") else "—"
        out.append(
            f"| {r['label']} | {'yes' if r['exact'] else 'no'} | {r['samples']} | {r['ms']:.3f}{star} | {clock} | "
            f"{r['rmse_255']:.2f} | {r['edge_rmse_255']:.2f} | {fl} | {node} | {stored} |"
        )
    if marked:
        out += [
            "",
            f"\\* median SM clock below the maximum {top:g} MHz (or not sampled): not comparable with the others.",
        ]
    done = {r["label"]: r for r in rec["rows"] if "skipped" not in r}
    for one, four, how in (
        (f"{AA_METHOD} x1", f"{AA_METHOD} x4", "the default, `raster: auto`"),
        (f"{AA_METHOD} hw x1", f"{AA_METHOD} hw x4", "both through the hardware rasterizer"),
    ):
        if one in done and four in done:
            a, b = done[one], done[four]
            out += [
                "",
                f"`{AA_METHOD}` 4 samples against 1 ({how}): edge RMSE "
                f"{a['edge_rmse_255'] / b['edge_rmse_255']:.2f}x lower (target >= 2); " + cost_ratio(a, b, top),
            ]
    return "\n".join(out) + "\n"


def chart(rec: dict, plt):
    """Frame time against RMSE and edge RMSE; the default's sample counts joined by a line."""
    rows = [r for r in rec["rows"] if "skipped" not in r]
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    for ax, key, title in ((axes[0], "rmse_255", "RMSE, all pixels"), (axes[1], "edge_rmse_255", "RMSE, edge pixels")):
        aa = sorted((r for r in rows if is_aa(r)), key=lambda r: r["samples"])
        ax.plot([r["ms"] for r in aa], [r[key] for r in aa], "-", color="tab:green", lw=1.5, zorder=1)
        # neighbours along x get staggered labels: exact methods share one error level
        for i, r in enumerate(sorted(rows, key=lambda r: r["ms"])):
            marker, color = ("o", "tab:blue") if r["exact"] else ("x", "tab:red")
            if is_aa(r):
                marker, color = "s", "tab:green"
            ax.scatter(r["ms"], r[key], marker=marker, color=color, zorder=2)
            dy = (-12, 4, 14, -22)[i % 4]
            ax.annotate(r["label"], (r["ms"], r[key]), fontsize=6, xytext=(3, dy), textcoords="offset points")
        ax.set_xscale("log")
        plain_log_axis(ax.xaxis)
        ax.set_xlabel(time_label(timer_of(rows), "frame time, ms (median)"))
        ax.set_ylabel("error against the supersampled exact frame (1/255)")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    ref = rec["reference"]
    fig.suptitle(
        f"{rec['scene']} at {rec['size']}²: reference {ref['method']} {ref['k']}x{ref['k']} "
        f"(blue: exact, red: approximate, green: {AA_METHOD} at 1/2/4/8 samples)"
    )
    fig.tight_layout()
    return fig


def main(argv: list[str] | None = None) -> int:
    """Measure speed against error per scene (or rebuild the tables and charts with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=5, scenes=True)
    add_reference_args(ap)
    ap.add_argument("--budget-s", type=float, default=3.0, help="a slower first frame: measure one frame")
    ap.add_argument(
        "--scene-budget-s", type=float, default=0.0, help="per scene (reference included): later configurations skipped"
    )
    ap.add_argument("--methods", nargs="*", help="methods at 1 sample (default: every method the device runs)")
    ap.add_argument("--samples", nargs="*", type=int, default=[1, 2, 4, 8], help=f"sample counts of {AA_METHOD}")
    ap.add_argument("--flip-workers", type=int, default=max(1, (os.cpu_count() or 2) // 2), help="0: inline")
    ap.add_argument("--aa-chart", action="store_true", help="the ways to anti-alias instead of the methods")
    args = ap.parse_args(argv)
    publish_folder = publish_aa_chart if args.aa_chart else publish
    if args.replot:
        res = Results.existing(args, argv)
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        paths = scene_paths(args)  # before the device and the workers: a wrong --scenes exits at once
        # spawned, not forked: the workers need no copy of a process that holds a GL context
        spawn = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(args.flip_workers, mp_context=spawn) if args.flip_workers > 0 else None
        device = open_device()
        res = Results(args, device.name, argv)
        make = aa_configs if args.aa_chart else method_configs
        progress = Progress(len(paths) * len(make(device.ctx, args)))
        for path in paths:
            rec = run_scene(device.ctx, path, args, pool, progress, make)
            rec.update(device=device.name, command=res.command)
            where = (
                res.dir / "aa_chart" / f"{rec['scene']}.json"
                if args.aa_chart
                else res.dir / rec["scene"] / "accuracy.json"
            )
            where.parent.mkdir(parents=True, exist_ok=True)
            where.write_text(json.dumps(rec, indent=1))
            publish_folder(res)  # after every scene: a run cut short keeps the scenes it finished
        if pool is not None:
            pool.shutdown()
    publish_folder(res)
    print(f"wrote {res.dir}" + ("/aa_chart.md" if args.aa_chart else ""), flush=True)
    return 0


def publish_aa_chart(res: Results) -> None:
    """The anti-aliasing chart's table and figure from every scene's JSON in aa_chart/ (earlier runs too)."""
    recs = [json.loads(p.read_text()) for p in sorted((res.dir / "aa_chart").glob("*.json"))]
    res.write_markdown(aa_chart.markdown(recs), stem="aa_chart")
    if recs:
        res.write_chart(lambda plt: aa_chart.chart(recs, plt), stem="aa_chart")


def publish(res: Results) -> None:
    """Each scene's page and chart from its JSON, and the folder's index (every scene in it, also those of
    earlier runs)."""
    recs = [json.loads(p.read_text()) for p in sorted(res.dir.glob("*/accuracy.json"))]
    index = ["# Speed against error on real scenes", ""]
    for rec in recs:
        res.write_markdown(markdown(rec), stem=f"{rec['scene']}/accuracy")
        res.write_chart(lambda plt, rec=rec: chart(rec, plt), stem=f"{rec['scene']}/accuracy")
        index.append(
            f"- [{rec['scene']}]({rec['scene']}/accuracy.md) ({rec['size']}², reference {rec['reference']['k']}x, "
            f"{rec['device']}): `{rec['command']}`"
        )
    res.write_markdown("\n".join(index), stem="README")


if __name__ == "__main__":
    raise SystemExit(main())
