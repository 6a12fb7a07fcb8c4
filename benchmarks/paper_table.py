"""The guacamole paper's Table 1 on real scenes, plus the stacks and frames that expose slow regimes.

Usage: python benchmarks/paper_table.py [--out DIR] [--scenes .scenes] [--scene-names NAME ...] [--size 1024]
                                        [--frames 8] [--warmup-s 1.5] [--methods ID ...]
                                        [--raster hardware compute] [--skip-stacks] [--loop-frames 24] [--replot]
       python benchmarks/paper_table.py scaling [--sizes 512 ... 4096] [--field 1 4 16 64] [--budget-s 225] ...

For every scene of the paper's Table 1 found in --scenes (dragons.yaml, sponza_dabrovic_v1/v2.yaml,
hairball_v1/v2.yaml: ../shared/scenes, the hairball written by its make_hairball.py) and every method
(the one-pass A-buffer methods, the best peeling method, unsorted blending), each through every
--raster choice the method has (transparency.raster; compute/ORDER also sets raster_order): per-pass
times (median of --frames after --warmup-s seconds of untimed frames, held at the full SM clock), the
frame's wall time in an application loop without read-back, fragments stored and culled, memory, the
SM clock, and the ratio to the paper's PreSortLF* figure (GTX 980). Then stacks of full-screen quads
(1, 2, 4, 8, 64 layers, unlit, alpha 0.5): geometry time per stored fragment; and the empty frame.
Writes benchmarks/results/<device>/paper_table/paper_table.{json,md,png}.

`scaling` (guaca_py/benchmarking/scaling.py, `scaling --help`) measures how cost grows with the
work on the dragons and hairball_v1: frame sizes 512² to 4096², a stereo pair of 2048² views
(Renderer.render_views) against one 2048x4096 frame, fields of 1 to 64 dragons; presort_lf_et and
the next fastest exact method, `raster: auto` beside `hardware`. Writes
benchmarks/results/<device>/paper_table/scaling.{json,md,png} and the fields' field_<n>.yaml.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from guaca_py import GuacaError, Renderer, UnsupportedMethodError
from guaca_py.benchmarking import (
    Progress,
    Results,
    bench_args,
    header,
    measure_point,
    open_device,
    plain_log_axis,
    raster_overrides,
    scaling,
    scene_paths,
    time_label,
    timer_of,
)
from guaca_py.benchmarking.scenes import quad_stack
from guaca_py.gpu_timer import Timestamps
from guaca_py.scene.graph import Camera, Scene
from guaca_py.scene.loader import load_scene

# scene file -> (paper's PreSortLF* total on a GTX 980 in ms, paper scene name)
PAPER = {
    "dragons": (3.0, "Dragons"),
    "sponza_dabrovic_v1": (6.6, "Atrium Sponza v1 (Crytek)"),
    "sponza_dabrovic_v2": (6.5, "Atrium Sponza v2 (Crytek)"),
    "hairball_v1": (39.6, "Hairball v1"),
    "hairball_v2": (58.0, "Hairball v2"),
}
# the exact one-pass A-buffer methods, held to <= 2x unsorted_blend
ONE_PASS_EXACT = (
    "presort_lf_et",
    "presort_lf",
    "presort_lf_merge2_et",
    "presort_cs_et",
    "presort_cs",
    "post_sort",
    "post_merge16",
)
METHODS = [*ONE_PASS_EXACT, "multilayer_depth_peeling", "unsorted_blend"]
STACK_LAYERS = (1, 2, 4, 8, 64)
STACK_METHODS = ("presort_lf_et", "post_sort")
# the benchmark owns its context: no host GL state to save and restore around each frame
# (that guard costs ~1 ms of CPU per call, which the frame loop's wall time would carry)
_OWN = {"restore_host_state": False}


def loop_wall_ms(renderer, scene, size: int, frames: int, stats: bool) -> dict:
    """Per frame of `frames` renders without read-back: wall time from an idle GPU to the last one's end,
    wall time inside render() calls, and CPU time of this process (render() taking as long as the
    GPU while the CPU idles means it waited for the GPU: a sync in the frame; `thread_cpu`: the calling
    thread's CPU time alone, without the driver's own threads)."""
    marks = Timestamps()  # GPU timestamps before and after each frame: read after the loop, no sync in it
    renderer.ctx.finish()
    t0, c0, h0 = time.perf_counter(), time.process_time(), time.thread_time()
    for _ in range(frames):
        marks.mark("idle")  # span from the previous frame's end: the GPU had nothing to run
        renderer.render(scene, size, size, read_back=False, stats=stats)
        marks.mark("frame")
    t1, c1, h1 = time.perf_counter(), time.process_time(), time.thread_time()
    renderer.ctx.finish()
    t2 = time.perf_counter()
    spans = marks.spans_ms()
    marks.release()
    row = {"wall": (t2 - t0) * 1e3 / frames, "submit": (t1 - t0) * 1e3 / frames, "cpu": (c1 - c0) * 1e3 / frames}
    row["thread_cpu"] = (h1 - h0) * 1e3 / frames
    if "frame" in spans:  # GPU time of the loop's own frames, and the GPU's idle time between them
        row["gpu"] = spans["frame"] / frames
        row["idle"] = spans.get("idle", 0.0) / max(1, frames - 1)
    return row


def time_row(renderer, scene, args, warmup_s: float | None = None) -> dict:
    """One configuration: per-pass medians held at the full clock, then the application loop's wall time."""

    def loops() -> dict:
        # frame loops as an application runs them, without read-back: with per-pass timers (the
        # previous frame's), and without them (stats=False) over more frames, so that the GPU's
        # idle start (the first frame's CPU work) and the final wait weigh less
        timed = loop_wall_ms(renderer, scene, args.size, args.frames, stats=True)
        loop = loop_wall_ms(renderer, scene, args.size, args.loop_frames, stats=False)
        return {
            "loop_wall_ms": loop["wall"],
            "loop_submit_ms": loop["submit"],  # inside render() calls
            "loop_cpu_ms": loop["cpu"],
            "loop_gpu_ms": loop.get("gpu"),  # GPU time per loop frame (timestamps), None without them
            "loop_gpu_idle_ms": loop.get("idle"),
            "loop_wall_timed_ms": timed["wall"],
        }

    point = measure_point(
        renderer,
        scene,
        args.size,
        frames=args.frames,
        warmup=args.warmup,
        warmup_s=args.warmup_s if warmup_s is None else warmup_s,
        hold_s=0.0,  # the loops keep the GPU busy under the sampler
        slow_s=0.5,
        slow_frames=3,
        then=loops,
    )
    s = point.last.stats
    return {
        **point.as_dict(),
        "fragments": s.get("fragments", {}),
        "memory": s.get("memory", {}),
        "regrown": s.get("regrown", 0),
        "warnings": s.get("warnings", []),
        "raster": s.get("raster"),
    }


def make_renderer(ctx, mid: str, raster: str) -> Renderer | None:
    """A default-pipeline Renderer for `mid` through `raster` ('compute/tile': with that raster_order);
    None where the method has no such rasterizer."""
    overrides = raster_overrides(raster)
    kind = overrides["raster"]
    try:
        return Renderer("default", ctx=ctx, method=mid, method_overrides=overrides, **_OWN)
    except UnsupportedMethodError:
        if kind == "compute":
            return None  # the method draws through the fragment pipeline only
        raise


def scene_rows(args, ctx, out: dict, progress: Progress, paths: list[Path]) -> None:
    """Every (scene, method, rasterizer) of Table 1."""
    for path in paths:
        paper_ms, paper_name = PAPER[path.stem]
        t0 = time.perf_counter()
        scene = load_scene(path)
        progress.note(f"{path.stem}: loaded in {time.perf_counter() - t0:.1f} s")
        rows = out.setdefault("scenes", {}).setdefault(path.stem, {"paper_ms": paper_ms, "paper_scene": paper_name})
        for mid, raster in [(m, r) for m in args.methods for r in args.raster]:
            key = f"{mid} ({raster})"
            r = None
            try:
                r = make_renderer(ctx, mid, raster)
                if r is None:
                    progress.step(f"{path.stem} {key}: no such rasterizer for this method")
                    continue
                row = time_row(r, scene, args)
            except GuacaError as exc:
                row = {"failed": str(exc)}
            finally:
                if r is not None:
                    r.release()
            rows[key] = row
            if "total_ms" not in row:
                progress.step(f"{path.stem} {key}: failed: {row['failed']}")
                continue
            row["ratio_to_paper"] = row["total_ms"] / paper_ms
            mhz = row["clock"]["sm_clock_mhz_median"] if row["clock"] else "—"
            progress.step(
                f"{path.stem} {key:<34} total {row['total_ms']:9.3f} ms  loop wall {row['loop_wall_ms']:9.3f} ms  "
                f"stored {row['fragments'].get('stored', 0):>10}  SM {mhz} MHz"
            )


def stack_rows(args, ctx, out: dict, progress: Progress) -> None:
    """Full-screen stacks: geometry ns per stored fragment; and the empty frame."""
    r = Renderer("default", ctx=ctx, **_OWN)
    empty = Scene(nodes=[], camera=Camera(position=[0, 0, 1], target=[0, 0, 0]), lights=[], background=[0, 0, 0])
    out["empty"] = time_row(r, empty, args, warmup_s=0.5)
    r.release()
    progress.step(f"empty frame: {out['empty']['total_ms']:.4f} ms, loop wall {out['empty']['loop_wall_ms']:.3f} ms")
    for mid in STACK_METHODS:
        r = make_renderer(ctx, mid, "hardware")
        for layers in STACK_LAYERS:
            row = time_row(r, quad_stack(layers), args, warmup_s=min(args.warmup_s, 0.5))
            stored = max(1, row["fragments"].get("stored", 0))
            row["geometry_ns_per_fragment"] = row["passes_ms"]["geometry"] * 1e6 / stored
            out.setdefault("stacks", {}).setdefault(mid, {})[str(layers)] = row
            progress.step(
                f"stack {mid:<14} {layers:>3} layers: geometry {row['passes_ms']['geometry']:8.3f} ms "
                f"= {row['geometry_ns_per_fragment']:6.2f} ns/fragment, total {row['total_ms']:.3f} ms"
            )
        r.release()


def timed_rows(out: dict) -> list[dict]:
    """Every timed row of the record (scenes, stacks, empty frame)."""
    rows = [r for s in out.get("scenes", {}).values() for r in s.values() if isinstance(r, dict)]
    rows += [r for m in out.get("stacks", {}).values() for r in m.values()]
    return rows + ([out["empty"]] if out.get("empty") else [])


def acceptance_lines(out: dict) -> list[str]:
    """Per scene: presort_lf_et against a tenth of the paper's time, the worst exact A-buffer against unsorted_blend."""
    lines = ["", "## Against the targets", ""]
    lines += [
        "| scene | presort_lf_et ms | target (paper / 10) | over the target | slowest exact A-buffer / unsorted_blend "
        "| most loop wall over loop GPU (≤ 1 ms) |",
        "|---|---|---|---|---|---|",
    ]
    for stem, rows in out.get("scenes", {}).items():
        timed = {k: r for k, r in rows.items() if isinstance(r, dict) and "total_ms" in r}
        et = next((r for k, r in timed.items() if k.startswith("presort_lf_et (")), None)
        blend = next((r for k, r in timed.items() if k.startswith("unsorted_blend (")), None)
        target = rows["paper_ms"] / 10
        cells = [stem, "—", f"{target:.2f}", "—", "—", "—"]
        if et:
            cells[1], cells[3] = f"{et['total_ms']:.3f}", f"{et['total_ms'] / target:.1f}x"
        exact = {k: r for k, r in timed.items() if k.split(" (")[0] in ONE_PASS_EXACT}
        if blend and exact:
            key, worst = max(exact.items(), key=lambda kv: kv[1]["total_ms"])
            cells[4] = f"{worst['total_ms'] / blend['total_ms']:.2f}x ({key})"
        over = {k: r["loop_wall_ms"] - r["loop_gpu_ms"] for k, r in timed.items() if r.get("loop_gpu_ms") is not None}
        if over:
            key = max(over, key=over.get)
            cells[5] = f"{over[key]:+.3f} ms ({key})"
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def loop_lines(out: dict) -> list[str]:
    """Per row: the timed frames' total against the application loop's wall time, time inside render() and CPU time."""
    rows = [
        (stem, key, r)
        for stem, scene in out.get("scenes", {}).items()
        for key, r in scene.items()
        if isinstance(r, dict) and "loop_submit_ms" in r
    ]
    if not rows:
        return []
    lines = ["", f"## Frame loop ({out.get('loop_frames', 24)} frames, no read-back, no timers), ms per frame", ""]
    lines += [
        "`loop GPU`: the loop's own frames on the GPU, from a timestamp before each frame to one after it; "
        "`GPU idle`: from one frame's end to the next one's start (the GPU waiting for the CPU). "
        "`total` is the timed frames' (each read back, its passes timed one by one).",
        "",
        "| scene | method | total | loop GPU | GPU idle | loop wall | wall - loop GPU | inside render() | CPU |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for stem, key, r in rows:
        gpu, idle = r.get("loop_gpu_ms"), r.get("loop_gpu_idle_ms")
        over = f"{r['loop_wall_ms'] - gpu:+.3f}" if gpu is not None else "—"
        lines.append(
            f"| {stem} | {key} | {r['total_ms']:.3f} | {'—' if gpu is None else f'{gpu:.3f}'} | "
            f"{'—' if idle is None else f'{idle:.3f}'} | {r['loop_wall_ms']:.3f} | {over} | "
            f"{r['loop_submit_ms']:.3f} | {r['loop_cpu_ms']:.3f} |"
        )
    return lines


def markdown(out: dict) -> str:
    """paper_table.md: Table 1, the targets, the frame loop, the stacks and the empty frame."""
    timer = timer_of(timed_rows(out))
    lines = header(f"Table 1 at {out['size']}²", out["device"], out["command"], timer)
    lines += [
        f"`loop wall ms`: wall time per frame of {out.get('loop_frames', 24)} renders without read-back and without "
        "timers (stats=False), in brackets of the timed frames with the previous frame's timers.",
        "",
        "| scene | method | geometry | light culling | composite | post | total ms | loop wall ms | "
        "stored | ET culled | pool MiB (used) | SM MHz | × paper |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for stem, rows in out.get("scenes", {}).items():
        for mid, row in rows.items():
            if not isinstance(row, dict):
                continue
            if "failed" in row:
                lines.append(f"| {stem} | {mid} | failed: {row['failed']} |")
                continue
            p = row["passes_ms"]
            post = sum(v for k, v in p.items() if k not in ("geometry", "light_culling", "composite"))
            fr, mem = row["fragments"], row["memory"]
            pool = mem.get("abuffer_pool", mem.get("multilayer_pool", 0)) / 2**20
            used = mem.get("abuffer_pool_used", 0) / 2**20
            clock = row["clock"]["sm_clock_mhz_median"] if row["clock"] else "—"
            lines.append(
                f"| {stem} | {mid} | {p.get('geometry', 0):.3f} | {p.get('light_culling', 0):.3f} | "
                f"{p.get('composite', 0):.3f} | {post:.3f} | **{row['total_ms']:.3f}** | "
                f"{row['loop_wall_ms']:.3f} ({row.get('loop_wall_timed_ms', 0):.3f}) | "
                f"{fr.get('stored', 0)} | {fr.get('early_termination_culled', 0)} | {pool:.1f} ({used:.1f}) | "
                f"{clock} | {row['ratio_to_paper']:.2f} |"
            )
    lines += acceptance_lines(out)
    lines += loop_lines(out)
    if out.get("stacks"):
        lines += ["", "## Full-screen stacks (back to front)", ""]
        lines += ["| method | layers | geometry ms | ns / stored fragment | total ms |", "|---|---|---|---|---|"]
        for mid, rows in out["stacks"].items():
            for layers, row in rows.items():
                lines.append(
                    f"| {mid} | {layers} | {row['passes_ms']['geometry']:.3f} | "
                    f"{row['geometry_ns_per_fragment']:.3f} | {row['total_ms']:.3f} |"
                )
    if out.get("empty"):
        e = out["empty"]
        lines += ["", f"Empty frame: {e['total_ms']:.4f} ms ({e['passes_ms']}), loop wall {e['loop_wall_ms']:.3f} ms"]
    return "\n".join(lines) + "\n"


def chart(out: dict):
    """A drawing function: one bar group per scene, total ms per method (log scale), the paper's figure as a line."""
    scenes = [
        s
        for s in out.get("scenes", {})
        if any("total_ms" in r for r in out["scenes"][s].values() if isinstance(r, dict))
    ]
    timer = timer_of(timed_rows(out))

    def draw(plt):
        if not scenes:
            return None
        cols = min(3, len(scenes))
        nrows = -(-len(scenes) // cols)
        height = 0.32 * max(len(out["scenes"][s]) for s in scenes) + 1.5
        fig, axes = plt.subplots(nrows, cols, figsize=(6.0 * cols, height * nrows), squeeze=False)
        for ax in axes.flat[len(scenes) :]:
            ax.axis("off")
        for ax, stem in zip(axes.flat, scenes):
            rows = {m: r for m, r in out["scenes"][stem].items() if isinstance(r, dict) and "total_ms" in r}
            names = list(rows)
            colors = ["#dd8452" if "(compute" in m else "#4c72b0" for m in names]  # compute rasterizer: orange
            bars = ax.barh(names, [rows[m]["total_ms"] for m in names], color=colors)
            ax.bar_label(bars, fmt="%.2f", fontsize=7, padding=2)
            paper = out["scenes"][stem]["paper_ms"]
            ax.axvline(paper, color="#c44e52", ls="--", label=f"paper PreSortLF* {paper} ms (GTX 980)")
            ax.axvline(paper / 10, color="#55a868", ls=":", label="target: paper / 10")
            ax.set_xscale("log")
            plain_log_axis(ax.xaxis)
            ax.margins(x=0.15)  # room for the bar labels
            ax.set_title(stem)
            ax.set_xlabel(time_label(timer, f"ms per frame ({out['size']}²)"))
            ax.invert_yaxis()
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)  # clear of the labels
        fig.tight_layout()
        return fig

    return draw


def main(argv: list[str] | None = None) -> int:
    """Run Table 1 (or rebuild its table and chart with --replot); `scaling ARGS` runs the scaling benchmark."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["scaling"]:
        return scaling.main(__file__, argv[1:])
    ap = bench_args(__file__, __doc__, size=1024, frames=8, scenes=True)
    ap.add_argument("--methods", nargs="*", default=METHODS)
    ap.add_argument(
        "--raster",
        nargs="*",
        default=["hardware", "compute"],
        help="rasterizers of transparent draws (auto, hardware, compute); compute/ORDER also sets raster_order",
    )
    ap.add_argument("--skip-stacks", action="store_true", help="leave out the empty frame and the full-screen stacks")
    ap.add_argument("--loop-frames", type=int, default=24, help="frames of the application loop")
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        out = res.read_json()
    else:
        paths = [p for p in scene_paths(args) if p.stem in PAPER]
        if not paths:
            raise SystemExit(f"no Table 1 scene in {args.scenes} ({', '.join(PAPER)}): copy ../shared/scenes there")
        device = open_device()
        res = Results(args, device.name, argv)
        out = {"size": args.size, "loop_frames": args.loop_frames}
        out["capabilities"] = device.caps.as_dict()
        stacks = 0 if args.skip_stacks else 1 + len(STACK_METHODS) * len(STACK_LAYERS)
        progress = Progress(stacks + len(paths) * len(args.methods) * len(args.raster))
        if not args.skip_stacks:
            stack_rows(args, device.ctx, out, progress)
        scene_rows(args, device.ctx, out, progress, paths)
    res.finish(out, markdown, chart)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
