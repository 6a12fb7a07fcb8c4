"""Speed against error on real scenes: every method, and the exact default at 1/2/4/8 samples.

Usage: python benchmarks/accuracy_scenes.py OUTDIR --scenes DIR [--size 1024] [--ref-k 8] [--tile 2048]
                                           [--frames 5] [--warmup 2] [--warmup-s 1.5] [--budget-s 3]
                                           [--scene-budget-s S] [--methods ID ...] [--samples 1 2 4 8]
                                           [--scene-names NAME ...] [--no-merged] [--replot]
With 4 among the sample counts, a row `presort_lf_et x4 merged` adds antialiasing.merge: adjacent
(through the compute rasterizer; approximate: merged samples take one triangle's shading).
Each scene (DIR/*.yaml) renders through guaca_py.accuracy.linear_pipeline: light culling as in
the default pipeline, no tone mapping or FXAA (linear output), threshold 0.999 for every method, so
exact methods differ from the reference by their aliasing alone. Reference: presort_lf (exact, no
early termination, hardware rasterizer) at --ref-k x the resolution, in tiles of at most --tile px,
box filtered (a tile whose fragments overflow the A-buffer pool is reported: use smaller tiles).
Error (linear, clipped to [0, 1], in 1/255): RMSE over all pixels, RMSE over edge pixels (their
k x k sub-pixels span > 0.05: silhouettes, boundaries, intersections), mean FLIP (sRGB-encoded,
when flip-evaluator is installed; computed in --flip-workers processes while the GPU renders on,
as one 1024² FLIP takes seconds of CPU). Time: median of --frames per-pass GPU timer sums after
at least --warmup frames and --warmup-s seconds of untimed rendering (wall time on software
rasterizers, which get no time-based warm-up), with the SM clock sampled; a configuration whose
median clock was below the maximum is measured again (up to 2 times) and marked in the table if it
still was. A configuration whose first frame exceeds --budget-s is measured on one frame; once a
scene has run for --scene-budget-s its remaining configurations are skipped (the sample counts run
first, and the first configuration always runs).
Writes OUTDIR/<scene>/accuracy.{json,md,png} and OUTDIR/README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from config_rows import config_rows  # noqa: E402
from gpu_clock import RETRIES, at_full_clock, max_sm_clock  # noqa: E402

from guaca_py import Renderer  # noqa: E402
from guaca_py.accuracy import edge_pixels, flip, linear_pipeline, rmse_255, supersampled  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.methods import method_class, method_ids  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402

AA_METHOD = "presort_lf_et"  # the exact default, measured at every sample count
REFERENCE_METHOD = "presort_lf"  # exact without early termination
HOLD_S = 0.3  # shortest sampled window of a timed configuration (the clock sampler polls every 100 ms)


def configs(
    caps, methods: list[str] | None, samples: list[int], merged: bool = True
) -> list[tuple[str, str, int, dict]]:
    """(label, method, samples, overrides): the default at each sample count (`raster: auto`: the compute
    rasterizer on a GPU, with coverage masks), the same with antialiasing.merge: adjacent at 4 samples
    (through the compute rasterizer, which merges; `merge` in the overrides is the pipeline's), the same
    through the hardware rasterizer at 1 and 4 samples, then every other method the device runs at 1 sample.
    The sample counts come first: a scene's time budget cuts the method list, not the anti-aliasing result."""
    ids = methods or [m for m in method_ids() if method_class(m).unsupported_reason(caps) is None]
    out = [(f"{AA_METHOD} x{n}", AA_METHOD, n, {}) for n in samples]
    if merged and 4 in samples:
        out.append((f"{AA_METHOD} x4 merged", AA_METHOD, 4, {"merge": "adjacent", "raster": "compute"}))
    out += [(f"{AA_METHOD} hw x{n}", AA_METHOD, n, {"raster": "hardware"}) for n in (1, 4) if n in samples]
    return out + [(m, m, 1, {}) for m in ids if m != AA_METHOD]


def warm_up(r: Renderer, scene, size: int, frames: int, seconds: float) -> None:
    """Untimed frames: at least `frames`, and for `seconds` (the GPU's clock ramps up only under load)."""
    t_end = time.perf_counter() + seconds
    n = 0
    while n < frames or time.perf_counter() < t_end:
        r.render(scene, size, size, read_back=False)
        r.ctx.finish()
        n += 1


def timed_frames(r: Renderer, scene, size: int, frames: int, hold_s: float) -> tuple[dict, object]:
    """Median per-pass and total ms of `frames` frames, and the last frame.

    Untimed frames follow until `hold_s` has passed: the clock sampler polls every 100 ms, and a
    short measurement would otherwise end before it has seen the GPU run these frames.
    """
    t0 = time.perf_counter()
    totals, passes = [], {}
    for _ in range(max(1, frames)):
        last = r.render(scene, size, size)
        for name, p in last.stats["passes"].items():
            passes.setdefault(name, []).append(p["ms"])
        totals.append(sum(p["ms"] for p in last.stats["passes"].values()))
    while time.perf_counter() - t0 < hold_s:
        r.render(scene, size, size, read_back=False)
        r.ctx.finish()
    return {
        "ms": statistics.median(totals),
        "pass_ms": {k: statistics.median(v) for k, v in passes.items()},
        "frames": len(totals),
        "timer": last.stats.get("timer"),
    }, last


def measure(r: Renderer, scene, size: int, args, warmup_s: float) -> tuple[dict, object]:
    """Timing of one configuration, and its last frame: warm-up, then --frames timed frames under the clock
    sampler, both again (up to gpu_clock.RETRIES times) while the sampled clock was below the maximum.
    A first frame slower than --budget-s: one timed frame, no warm-up (that frame kept the GPU busy)."""
    t0 = time.perf_counter()
    r.render(scene, size, size)  # pool growth and shader compilation happen here, untimed
    slow = time.perf_counter() - t0 > args.budget_s
    frames = 1 if slow else args.frames
    warm = None if slow else (lambda: warm_up(r, scene, size, args.warmup - 1, warmup_s))
    hold_s = HOLD_S if warmup_s > 0 else 0.0
    (timing, frame), clock, retries = at_full_clock(
        lambda: timed_frames(r, scene, size, frames, hold_s), warm_up=warm, share=1.0
    )
    timing.update(clock=clock.summary(), clock_retries=retries, warmup_s=0.0 if slow else warmup_s)
    return timing, frame


def below_max_clock(clock: dict | None, top: float | None) -> bool:
    """Whether a row is not known to have run at the maximum SM clock: its median was below `top`, or
    nothing was sampled on a device that has a maximum. Without a maximum (no nvidia-smi) never."""
    return top is not None and (clock is None or clock["sm_clock_mhz_median"] < top)


def top_clock(rec: dict) -> float | None:
    """The record's maximum SM clock; records made before it was stored: the highest clock any row sampled."""
    if "max_sm_clock_mhz" in rec:
        return rec["max_sm_clock_mhz"]
    seen = [r["clock"]["sm_clock_mhz_max"] for r in rec["rows"] if r.get("clock")]
    return max(seen) if seen else None


def reference(ctx, path: Path, scene, args):
    """The scene's exact frame at --ref-k x --size, box filtered, and its edge pixels (printed with its time)."""
    t0 = time.perf_counter()
    # the hardware rasterizer, as for every sample count: one set of coverage rules throughout
    ref_r = Renderer(linear_pipeline(1), ctx=ctx, method=REFERENCE_METHOD, method_overrides={"raster": "hardware"})
    ref = supersampled(ref_r, scene, args.size, args.size, args.ref_k, args.tile)
    ref_r.release()
    edges = edge_pixels(ref)
    print(
        f"{path.stem}: reference {args.ref_k}x ({ref.tiles} tiles of at most {args.tile}²) "
        f"{time.perf_counter() - t0:.1f} s, edge pixels {edges.mean():.1%}"
        + (f", OVERFLOW: {ref.overflow} fragments dropped (smaller --tile)" if ref.overflow else ""),
        flush=True,
    )
    return ref, edges


def errors(img, ref, edges, pool=None) -> dict:
    """RMSE, edge RMSE (1/255) and FLIP (a future where `pool` computes it) of a linear frame against `ref`."""
    return {
        "rmse_255": rmse_255(img, ref.image),
        "edge_rmse_255": rmse_255(img, ref.image, edges),
        "flip": pool.submit(flip, img, ref.image) if pool is not None else flip(img, ref.image),
    }


def add_common_args(ap: argparse.ArgumentParser) -> None:
    """Arguments every error benchmark takes: output, scenes, size, reference and timing."""
    ap.add_argument("out", type=Path)
    ap.add_argument("--scenes", type=Path, required=True, help="folder of scene YAMLs (e.g. ../shared/scenes)")
    ap.add_argument("--scene-names", nargs="*", help="only these scenes (file stems)")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--ref-k", type=int, default=8, help="reference supersampling factor (4 or 8)")
    ap.add_argument("--tile", type=int, default=2048, help="largest reference tile side in px")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2, help="untimed frames at least (the first included)")
    ap.add_argument(
        "--warmup-s", type=float, default=1.5, help="untimed rendering before timing (GPU timers only: the clock ramps)"
    )
    ap.add_argument("--budget-s", type=float, default=3.0, help="a slower first frame: measure one frame")


def scene_paths(args) -> list[Path]:
    """The scene YAMLs of --scenes, only those of --scene-names where given."""
    scenes = sorted(args.scenes.glob("*.yaml"))
    return [p for p in scenes if p.stem in args.scene_names] if args.scene_names else scenes


def run_scene(ctx, caps, path: Path, args, pool) -> dict:
    """Reference, then every configuration of one scene (until --scene-budget-s); the scene's JSON record."""
    t0 = time.perf_counter()
    scene = load_scene(path)
    size = args.size
    # no clock to ramp up on software rasterizers (their frames are timed on the wall clock)
    warmup_s = args.warmup_s if caps.gpu_timers else 0.0
    ref, edges = reference(ctx, path, scene, args)

    def measure_row(r: Renderer, row: dict) -> None:
        timing, frame = measure(r, scene, size, args, warmup_s)
        row.update(timing)
        row["samples"] = r.samples
        row.update(errors(frame.linear, ref, edges, pool))
        row["fragments"] = frame.stats.get("fragments", {})
        row["raster"] = frame.stats.get("raster", {}).get("why")
        row["memory"] = frame.stats.get("memory", {})
        row["warnings"] = frame.stats.get("warnings", [])

    def report(row: dict) -> None:
        fl = f"  FLIP {row['flip']:.4f}" if isinstance(row["flip"], float) else ""
        mhz = f"  {row['clock']['sm_clock_mhz_median']} MHz" if row["clock"] else ""
        again = f" ({row['clock_retries']} retries)" if row["clock_retries"] else ""
        print(
            f"  {row['label']:28s} {row['ms']:9.3f} ms  RMSE {row['rmse_255']:6.2f}  edge {row['edge_rmse_255']:6.2f}"
            f"{fl}{mhz}{again}  [{time.perf_counter() - t0:.0f} s]",
            flush=True,
        )

    def renderer(n: int, mid: str, overrides: dict):
        settings = {k: v for k, v in overrides.items() if k != "merge"}
        pipeline = linear_pipeline(n, merge=overrides.get("merge", "off"))
        return lambda: Renderer(pipeline, ctx=ctx, method=mid, method_overrides=settings or None)

    rows = config_rows(
        (
            (
                {
                    "label": label,
                    "method": mid,
                    "samples": n,
                    # merged samples take the shading of the triangle at the pixel centre: not exact
                    "exact": method_class(mid).exact and "merge" not in overrides,
                    "settings": overrides,
                },
                renderer(n, mid, overrides),
            )
            for label, mid, n, overrides in configs(caps, args.methods, args.samples, not args.no_merged)
        ),
        measure_row,
        report,
        t0,
        args.scene_budget_s,
    )
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
        "warmup_s": warmup_s,
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
        return "SM clock: not sampled (no nvidia-smi; on a software rasterizer times are wall times)."
    mark = "`*` marks frame times whose median clock was below it (or not sampled)."
    if "max_sm_clock_mhz" not in rec:
        return (
            f"SM clock maximum: {top:g} MHz (the highest clock sampled in this run). This run predates the "
            f"time-based warm-up and the retries: {mark}"
        )
    return (
        f"SM clock maximum: {top:g} MHz. Each configuration renders for {rec['warmup_s']:g} s before it is timed, "
        f"and is timed again (up to {RETRIES} times) while its median sampled clock is below the maximum; {mark}"
    )


def cost_ratio(one: dict, four: dict, auto: dict | None, top: float | None) -> str:
    """The frame-time part of the 4-against-1 sentence; no ratio between rows not both at the maximum clock."""
    low = [r for r in (one, four) if below_max_clock(r.get("clock"), top)]
    if low:
        why = ", ".join(f"{r['label']} at {mhz(r)}" for r in low)
        return f"frame time: no ratio, not every row ran at the maximum SM clock of {top:g} MHz ({why})."
    out = f"frame time {four['ms'] / one['ms']:.2f}x (target <= 1.6)"
    if auto is None:
        return out + "."
    if below_max_clock(auto.get("clock"), top):
        return out + f"; against the 1-sample default (`raster: auto`) no ratio: it ran at {mhz(auto)}."
    return out + f"; against the 1-sample default (`raster: auto`) {four['ms'] / auto['ms']:.2f}x."


def mhz(row: dict) -> str:
    """A row's median SM clock in words."""
    return f"{row['clock']['sm_clock_mhz_median']:g} MHz" if row.get("clock") else "an unsampled clock"


def markdown(rec: dict, command: str, device: str) -> str:
    """One scene's table."""
    ref = rec["reference"]
    top = top_clock(rec)
    overflow = ref.get("overflow", 0)
    out = [
        f"# {rec['scene']}: speed against error at {rec['size']}²",
        "",
        f"Device: {device}. Reference: `{ref['method']}` at {ref['k']}x ({ref['tiles']} tiles), box filtered"
        + (f", NOT EXACT: {overflow} fragments dropped by A-buffer overflow" if overflow else "")
        + f". Edge pixels (sub-pixels span > {ref['edge_tolerance']}): {rec['edge_pixels']}.",
        "Error in 1/255 of the linear output clipped to [0, 1]; time: median frame (sum of pass times).",
        clock_line(rec),
        "",
        f"Command: `{command}`",
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
        fl = f"{r['flip']:.4f}" if r.get("flip") is not None else "—"
        node = r["memory"].get("abuffer_node_bytes", "—")
        stored = r["fragments"].get("stored", "—")
        if r["fragments"].get("overflow"):  # the pool was at the device's limit: the image lacks these
            stored = f"{stored} (+{r['fragments']['overflow']} dropped)"
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
                f"{a['edge_rmse_255'] / b['edge_rmse_255']:.2f}x lower (target >= 2); " + cost_ratio(a, b, None, top),
            ]
    return "\n".join(out) + "\n"


def chart(rec: dict, path: Path) -> None:
    """Frame time against RMSE and edge RMSE; the default's sample counts joined by a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from chart_axes import plain_log_axis

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
        ax.set_xlabel("frame time (ms, median)")
        ax.set_ylabel("error against the supersampled exact frame (1/255)")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    ref = rec["reference"]
    fig.suptitle(
        f"{rec['scene']} at {rec['size']}²: reference {ref['method']} {ref['k']}x{ref['k']} "
        f"(blue: exact, red: approximate, green: {AA_METHOD} at 1/2/4/8 samples)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_args(ap)
    ap.add_argument(
        "--scene-budget-s", type=float, default=0.0, help="per scene (reference included): later configurations skipped"
    )
    ap.add_argument("--methods", nargs="*", help="methods at 1 sample (default: every method the device runs)")
    ap.add_argument("--samples", nargs="*", type=int, default=[1, 2, 4, 8], help=f"sample counts of {AA_METHOD}")
    ap.add_argument("--no-merged", action="store_true", help="leave out the 4-sample row with antialiasing.merge")
    ap.add_argument("--flip-workers", type=int, default=max(1, (os.cpu_count() or 2) // 2), help="0: inline")
    ap.add_argument("--replot", action="store_true", help="rebuild tables and charts from OUTDIR/*/accuracy.json")
    args = ap.parse_args(argv)
    command = "python benchmarks/accuracy_scenes.py " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    args.out.mkdir(parents=True, exist_ok=True)
    if not args.replot:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # spawned, not forked: the workers need no copy of a process that holds a GL context
        spawn = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(args.flip_workers, mp_context=spawn) if args.flip_workers > 0 else None
        ctx, caps = create_context()
        device = caps.gl_renderer
        for path in scene_paths(args):
            rec = run_scene(ctx, caps, path, args, pool)
            rec.update(device=device, command=command)
            d = args.out / rec["scene"]
            d.mkdir(exist_ok=True)
            (d / "accuracy.json").write_text(json.dumps(rec, indent=1))
        if pool is not None:
            pool.shutdown()
    # the index lists every scene in OUTDIR, also those of earlier runs
    recs = [json.loads(p.read_text()) for p in sorted(args.out.glob("*/accuracy.json"))]
    index = ["# Speed against error on real scenes", ""]
    for rec in recs:
        d = args.out / rec["scene"]
        (d / "accuracy.md").write_text(markdown(rec, rec["command"], rec["device"]))
        chart(rec, d / "accuracy.png")
        index.append(
            f"- [{rec['scene']}]({rec['scene']}/accuracy.md) ({rec['size']}², reference {rec['reference']['k']}x, "
            f"{rec['device']})"
        )
    (args.out / "README.md").write_text("\n".join(index) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
