"""The guacamole paper's Table 1 on real scenes, plus the stacks and frames that expose slow regimes.

Usage: python benchmarks/paper_table.py OUTDIR [--scenes DIR] [--size 1024] [--frames 8] [--warmup-s 1.5]
                                        [--only SCENE ...] [--methods ID ...] [--skip-stacks] [--empty-only]

For every scene of the paper's Table 1 found in --scenes (dragons.yaml, sponza_dabrovic_v1/v2.yaml,
hairball_v1/v2.yaml: see ../shared/scenes/README.md; the hairball is written by make_hairball.py)
and every method (all one-pass A-buffer methods, the best peeling method, unsorted blending), each
through every --raster choice the method has (transparency.raster: hardware, compute):
per-stage GPU times (timer queries, median of --frames after --warmup-s seconds of untimed frames),
the frame's wall time in a loop without read-back, fragments stored and culled, memory, the SM
clock while it ran, and the ratio to the paper's PreSortLF* figure (GTX 980). Then:
  * stacks of full-screen quads (1, 2, 4, 8, 64 layers, unlit, alpha 0.5) at --size: geometry
    time per stored fragment, the regime that must never come back unseen;
  * the empty frame (no nodes, no lights);
  * the read-back experiment: the 1-layer stack with GUACA_DIRECT_CPU_ACCESS=1 (the CPU writes and
    reads the shaders' counter buffer, as before) against the default staged access.
Writes OUTDIR/paper_table.json, paper_table.md and paper_table.png; prints progress while it runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from gpu_clock import RETRIES, ClockSampler  # noqa: E402

from guaca_py import GuacaError, Renderer  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.gpu_timer import Timestamps  # noqa: E402
from guaca_py.scene.graph import Camera, MaterialInstance, MeshData, Node, Scene, Transform  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402

# scene file -> (paper's PreSortLF* total on a GTX 980 in ms, paper scene name)
PAPER = {
    "dragons": (3.0, "Dragons"),
    "sponza_dabrovic_v1": (6.6, "Atrium Sponza v1 (Crytek)"),
    "sponza_dabrovic_v2": (6.5, "Atrium Sponza v2 (Crytek)"),
    "hairball_v1": (39.6, "Hairball v1"),
    "hairball_v2": (58.0, "Hairball v2"),
}
METHODS = [
    "presort_lf_et",
    "presort_lf",
    "presort_lf_merge2_et",
    "presort_cs_et",
    "presort_cs",
    "post_sort",
    "post_merge16",
    "multilayer_depth_peeling",
    "unsorted_blend",
]
STACK_LAYERS = (1, 2, 4, 8, 64)
# the benchmark owns its context: no host GL state to save and restore around each frame
# (that guard costs ~1 ms of CPU per call, which the frame loop's wall time would carry)
_OWN = {"restore_host_state": False}
STACK_METHODS = ("presort_lf_et", "post_sort")
LOOP_FRAMES = 24  # frames of the application loop (stats=False) behind `loop wall ms`


def progress(text: str) -> None:
    """One progress line with the time since start."""
    print(f"[{time.perf_counter() - _T0:7.1f} s] {text}", flush=True)


_T0 = time.perf_counter()


def time_frames(renderer, scene, size: int, warmup_s: float, frames: int, warmup_read_back: bool = False) -> dict:
    """time_once(), measured again (up to RETRIES times) while the SM clock was under 90% of its maximum."""
    for attempt in range(RETRIES + 1):
        row = time_once(renderer, scene, size, warmup_s, frames, warmup_read_back)
        row["clock_retries"] = attempt
        if not row.pop("_throttled"):
            break
    return row


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
    row["thread_cpu"] = (h1 - h0) * 1e3 / frames  # the calling thread alone (Python and the GL calls it makes)
    if "frame" in spans:  # GPU time of the loop's own frames, and the GPU's idle time between them
        row["gpu"] = spans["frame"] / frames
        row["idle"] = spans.get("idle", 0.0) / max(1, frames - 1)
    return row


def time_once(renderer, scene, size: int, warmup_s: float, frames: int, warmup_read_back: bool = False) -> dict:
    """Untimed frames for `warmup_s` seconds (the GPU clock ramps up), then per-pass medians and loop wall time."""
    t_end = time.perf_counter() + warmup_s
    n_warm = 0
    while n_warm < 2 or time.perf_counter() < t_end:
        t0 = time.perf_counter()
        renderer.render(scene, size, size, read_back=warmup_read_back)
        renderer.ctx.finish()
        n_warm += 1
        if time.perf_counter() - t0 > 0.5:  # a slow configuration: fewer frames keep the run bounded
            frames = min(frames, 3)
            break
    samples: dict[str, list[float]] = {}
    totals = []
    with ClockSampler(period_ms=50) as clock:
        for _ in range(frames):
            res = renderer.render(scene, size, size)  # this frame's own timers (waits for it)
            for name, p in res.stats["passes"].items():
                samples.setdefault(name, []).append(p["ms"])
            totals.append(sum(p["ms"] for p in res.stats["passes"].values()))
        # frame loops as an application runs them, without read-back: with per-pass timers (the
        # previous frame's), and without them (stats=False) over more frames, so that the GPU's
        # idle start (the first frame's CPU work) and the final wait weigh less
        loop_timed = loop_wall_ms(renderer, scene, size, frames, stats=True)
        loop = loop_wall_ms(renderer, scene, size, LOOP_FRAMES if frames > 3 else frames, stats=False)
    last = renderer.render(scene, size, size)
    return {
        "passes_ms": {k: statistics.median(v) for k, v in samples.items()},
        "total_ms": statistics.median(totals),
        "loop_wall_ms": loop["wall"],
        "loop_submit_ms": loop["submit"],  # inside render() calls
        "loop_cpu_ms": loop["cpu"],
        "loop_gpu_ms": loop.get("gpu"),  # GPU time per loop frame (timestamps), None without them
        "loop_gpu_idle_ms": loop.get("idle"),
        "loop_wall_timed_ms": loop_timed["wall"],
        "warmup_frames": n_warm,
        "frames": frames,
        "fragments": last.stats.get("fragments", {}),
        "memory": last.stats.get("memory", {}),
        "regrown": last.stats.get("regrown", 0),
        "warnings": last.stats.get("warnings", []),
        "timer": last.stats.get("timer"),
        "raster": last.stats.get("raster"),
        "clock": clock.summary(),
        "_throttled": clock.throttled(),
    }


def quad_stack(layers: int) -> Scene:
    """`layers` full-screen unlit quads at alpha 0.5, drawn back to front."""
    p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32) * 4.0
    mesh = MeshData(
        p,
        np.tile(np.float32([0, 0, 1]), (4, 1)),
        np.float32([[0, 0], [1, 0], [1, 1], [0, 1]]),
        np.uint32([[0, 1, 2], [0, 2, 3]]),
        "stack_quad",
    )
    nodes = []
    for i in range(layers):
        z = -1.0 - 2.0 * (layers - 1 - i) / max(1, layers)  # back to front
        color = [(i * 37 % 11) / 10, (i * 17 % 7) / 6, (i * 5 % 3) / 2]
        nodes.append(
            Node(
                f"layer{i}",
                mesh=mesh,
                transform=Transform(translation=[0, 0, z]),
                material=MaterialInstance("unlit", {"color": color, "alpha": 0.5}),
            )
        )
    cam = Camera(position=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0], fov_y=90, near=0.1, far=10)
    return Scene(nodes=nodes, camera=cam, lights=[], background=[0, 0, 0])


def scene_rows(args, ctx, out: dict) -> None:
    """Every (scene, method) of Table 1."""
    for stem, (paper_ms, paper_name) in PAPER.items():
        path = Path(args.scenes) / f"{stem}.yaml"
        if args.only and stem not in args.only:
            continue
        if not path.is_file():
            progress(f"{stem}: {path} missing, skipped")
            continue
        t0 = time.perf_counter()
        scene = load_scene(path)
        progress(f"{stem}: loaded in {time.perf_counter() - t0:.1f} s")
        rows = out.setdefault("scenes", {}).setdefault(stem, {"paper_ms": paper_ms, "paper_scene": paper_name})
        for mid, raster in [(m, r) for m in args.methods for r in args.raster]:
            key = f"{mid} ({raster})"
            try:
                r = make_renderer(ctx, mid, raster)
            except GuacaError as exc:
                rows[key] = {"failed": str(exc)}
                progress(f"  {key}: {exc}")
                continue
            if r is None:
                continue  # the method has no such rasterizer choice
            try:
                row = time_frames(r, scene, args.size, args.warmup_s, args.frames)
            except GuacaError as exc:
                row = {"failed": str(exc)}
            finally:
                r.release()
            if "total_ms" in row:
                row["ratio_to_paper"] = row["total_ms"] / paper_ms
                progress(
                    f"  {key:<36} total {row['total_ms']:9.3f} ms  loop wall {row['loop_wall_ms']:9.3f} ms  "
                    f"stored {row['fragments'].get('stored', 0):>10}  "
                    f"clock {row['clock']['sm_clock_mhz_median'] if row['clock'] else '?'} MHz"
                )
            rows[key] = row


def make_renderer(ctx, mid: str, raster: str):
    """A default-pipeline Renderer for `mid` with `raster` ('compute/tile': with that raster_order); None when n/a."""
    from guaca_py.methods import method_class

    cls = method_class(mid)
    if "raster" not in cls.settings_schema():
        return Renderer("default", ctx=ctx, method=mid, **_OWN) if raster in ("hardware", "auto") else None
    if raster.startswith("compute") and not cls.compute_raster:
        return None  # the method draws through the fragment pipeline only
    kind, _, order = raster.partition("/")
    overrides = {"raster": kind, **({"raster_order": order} if order else {})}
    return Renderer("default", ctx=ctx, method=mid, method_overrides=overrides, **_OWN)


def stack_rows(args, ctx, out: dict) -> None:
    """Full-screen stacks: geometry ns per stored fragment."""
    for mid in STACK_METHODS:
        r = make_renderer(ctx, mid, "hardware")
        for layers in STACK_LAYERS:
            row = time_frames(r, quad_stack(layers), args.size, min(args.warmup_s, 0.5), args.frames)
            stored = max(1, row["fragments"].get("stored", 0))
            row["geometry_ns_per_fragment"] = row["passes_ms"]["geometry"] * 1e6 / stored
            out.setdefault("stacks", {}).setdefault(mid, {})[str(layers)] = row
            progress(
                f"stack {mid:<14} {layers:>3} layers: geometry {row['passes_ms']['geometry']:8.3f} ms "
                f"= {row['geometry_ns_per_fragment']:6.2f} ns/fragment, total {row['total_ms']:.3f} ms"
            )
        r.release()


def empty_and_experiment(args, ctx, out: dict) -> None:
    """The empty frame, and the CPU-access experiment on the 1-layer stack."""
    r = Renderer("default", ctx=ctx, **_OWN)
    empty = Scene(nodes=[], camera=Camera(position=[0, 0, 1], target=[0, 0, 0]), lights=[], background=[0, 0, 0])
    out["empty"] = time_frames(r, empty, args.size, 0.5, args.frames)
    r.release()
    progress(f"empty frame: {out['empty']['total_ms']:.4f} ms GPU, loop wall {out['empty']['loop_wall_ms']:.3f} ms")
    progress(f"empty frame passes: {out['empty']['passes_ms']}")
    if args.empty_only:  # the same frame with every pass separate (tone mapping not fused into the composite)
        r = Renderer("default", ctx=ctx, fuse_passes=False, **_OWN)
        out["empty_unfused"] = time_frames(r, empty, args.size, 0.5, args.frames)
        r.release()
        progress(f"empty frame, passes not fused: {out['empty_unfused']['total_ms']:.4f} ms GPU")
        progress(f"empty frame, passes not fused: {out['empty_unfused']['passes_ms']}")
        return
    for label, value in (("staged", "0"), ("direct", "1")):
        os.environ["GUACA_DIRECT_CPU_ACCESS"] = value
        r = make_renderer(ctx, "presort_lf_et", "hardware")  # fresh buffers for each access pattern
        # warm-up frames read back too: the driver moves a buffer after the CPU has read it repeatedly
        row = time_frames(r, quad_stack(1), args.size, 0.5, args.frames, warmup_read_back=True)
        r.release()
        out.setdefault("cpu_access_experiment", {})[label] = row
        progress(f"1-layer stack, {label} CPU access: geometry {row['passes_ms']['geometry']:.3f} ms")
    os.environ.pop("GUACA_DIRECT_CPU_ACCESS", None)


def one_pass_exact() -> set[str]:
    """The exact one-pass A-buffer methods (those that take compute-rasterized fragments), held to <= 2x unsorted_blend."""
    from guaca_py.methods import method_class, method_ids

    return {m for m in method_ids() if method_class(m).compute_raster and method_class(m).exact}


def acceptance_lines(out: dict) -> list[str]:
    """Per scene: presort_lf_et against a tenth of the paper's time, the worst exact A-buffer against unsorted_blend."""
    lines = ["", "## Against the targets", ""]
    lines += [
        "| scene | presort_lf_et ms | target (paper / 10) | over the target | slowest exact A-buffer / unsorted_blend "
        "| most loop wall over loop GPU (≤ 1 ms) |",
        "|---|---|---|---|---|---|",
    ]
    exact_ids = one_pass_exact()
    for stem, rows in out.get("scenes", {}).items():
        timed = {k: r for k, r in rows.items() if isinstance(r, dict) and "total_ms" in r}
        et = next((r for k, r in timed.items() if k.startswith("presort_lf_et (")), None)
        blend = next((r for k, r in timed.items() if k.startswith("unsorted_blend (")), None)
        target = rows["paper_ms"] / 10
        cells = [stem, "—", f"{target:.2f}", "—", "—", "—"]
        if et:
            cells[1], cells[3] = f"{et['total_ms']:.3f}", f"{et['total_ms'] / target:.1f}x"
        exact = {k: r for k, r in timed.items() if k.split(" (")[0] in exact_ids}
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
    """Per row: GPU total against the application loop's wall time, time inside render() and CPU time."""
    rows = [
        (stem, key, r)
        for stem, scene in out.get("scenes", {}).items()
        for key, r in scene.items()
        if isinstance(r, dict) and "loop_submit_ms" in r
    ]
    if not rows:
        return []
    lines = ["", f"## Frame loop ({LOOP_FRAMES} frames, no read-back, no timers), ms per frame", ""]
    lines += [
        "`loop GPU`: the loop's own frames on the GPU, from a timestamp before each frame to one after it; "
        "`GPU idle`: from one frame's end to the next one's start (the GPU waiting for the CPU). "
        "`GPU total` is the timed frames' (each read back, its passes timed one by one).",
        "",
        "| scene | method | GPU total | loop GPU | GPU idle | loop wall | wall - loop GPU | inside render() | CPU |",
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


def write_markdown(out: dict, path: Path) -> None:
    """paper_table.md: Table 1, stacks, empty frame and the experiment."""
    lines = [f"# Table 1 at {out['size']}² on {out['device']}", "", f"Command: `{out['command']}`", ""]
    lines += [
        f"`loop wall ms`: wall time per frame of {LOOP_FRAMES} renders without read-back and without timers "
        "(stats=False), in brackets of the timed frames with the previous frame's timers.",
        "",
        "| scene | method | geometry | light culling | composite | post | total GPU ms | loop wall ms | "
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
            clock = row["clock"]["sm_clock_mhz_median"] if row["clock"] else "?"
            lines.append(
                f"| {stem} | {mid} | {p.get('geometry', 0):.3f} | {p.get('light_culling', 0):.3f} | "
                f"{p.get('composite', 0):.3f} | {post:.3f} | **{row['total_ms']:.3f}** | {row['loop_wall_ms']:.3f} ({row.get('loop_wall_timed_ms', 0):.3f}) | "
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
        lines += [
            "",
            f"Empty frame: {e['total_ms']:.4f} ms GPU ({e['passes_ms']}), loop wall {e['loop_wall_ms']:.3f} ms",
        ]
    if out.get("cpu_access_experiment"):
        lines += ["", "## CPU access experiment (1-layer stack, presort_lf_et)", ""]
        for label, row in out["cpu_access_experiment"].items():
            lines.append(f"- {label}: geometry {row['passes_ms']['geometry']:.3f} ms, total {row['total_ms']:.3f} ms")
    path.write_text("\n".join(lines) + "\n")


def plot(out: dict, path: Path) -> None:
    """One bar group per scene: total GPU ms per method (log scale), the paper's figure as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from chart_axes import plain_log_axis

    scenes = [
        s
        for s in out.get("scenes", {})
        if any("total_ms" in r for r in out["scenes"][s].values() if isinstance(r, dict))
    ]
    if not scenes:
        return
    cols = min(3, len(scenes))
    nrows = -(-len(scenes) // cols)
    height = 0.32 * max(len(out["scenes"][s]) for s in scenes) + 1.5
    fig, axes = plt.subplots(nrows, cols, figsize=(6.0 * cols, height * nrows), squeeze=False)
    for ax in axes.flat[len(scenes) :]:
        ax.axis("off")
    for ax, stem in zip(axes.flat, scenes):
        rows = {m: r for m, r in out["scenes"][stem].items() if isinstance(r, dict) and "total_ms" in r}
        names = list(rows)
        colors = ["#dd8452" if "(compute)" in m else "#4c72b0" for m in names]  # compute rasterizer: orange
        bars = ax.barh(names, [rows[m]["total_ms"] for m in names], color=colors)
        ax.bar_label(bars, fmt="%.2f", fontsize=7, padding=2)
        paper = out["scenes"][stem]["paper_ms"]
        ax.axvline(paper, color="#c44e52", ls="--", label=f"paper PreSortLF* {paper} ms (GTX 980)")
        ax.axvline(paper / 10, color="#55a868", ls=":", label="target: paper / 10")
        ax.set_xscale("log")
        plain_log_axis(ax.xaxis)
        ax.margins(x=0.15)  # room for the bar labels
        ax.set_title(stem)
        ax.set_xlabel("GPU ms per frame (1024²)")
        ax.invert_yaxis()
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)  # below: clear of the bar labels
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def replot(files: list[Path], outdir: Path) -> None:
    """Merge the scene rows of several runs (e.g. one per rasterizer) into one table and chart."""
    merged: dict = {}
    for f in files:
        run = json.loads(f.read_text())
        if not merged:
            merged = {k: v for k, v in run.items() if k != "scenes"}
            merged["command"] = "python3 benchmarks/paper_table.py OUT --replot " + " ".join(str(x) for x in files)
        for stem, rows in run.get("scenes", {}).items():
            merged.setdefault("scenes", {}).setdefault(stem, {}).update(rows)
    (outdir / "paper_table.json").write_text(json.dumps(merged, indent=1, default=str))
    write_markdown(merged, outdir / "paper_table.md")
    plot(merged, outdir / "paper_table.png")


def main() -> None:
    global LOOP_FRAMES
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--scenes", default=str(ROOT / ".scenes"))
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--warmup-s", type=float, default=1.5)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--methods", nargs="*", default=METHODS)
    ap.add_argument(
        "--raster",
        nargs="*",
        default=["hardware", "compute"],
        help="rasterizers of transparent draws; compute/ORDER also sets transparency.raster_order",
    )
    ap.add_argument("--skip-stacks", action="store_true")
    ap.add_argument("--loop-frames", type=int, default=LOOP_FRAMES, help="frames of the application loop")
    ap.add_argument(
        "--empty-only", action="store_true", help="only the empty frame (with and without pass fusion); JSON only"
    )
    ap.add_argument("--replot", nargs="*", metavar="JSON", help="no rendering: merge these result files into OUTDIR")
    args = ap.parse_args()
    LOOP_FRAMES = args.loop_frames  # read by time_once() and the tables
    outdir = Path(args.outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    if args.replot:
        replot([Path(p) for p in args.replot], outdir)
        return
    ctx, caps = create_context()
    out = {
        "device": caps.gl_renderer,
        "size": args.size,
        "command": "python3 benchmarks/paper_table.py " + " ".join(sys.argv[1:]),
        "capabilities": caps.as_dict(),
    }
    if args.empty_only:
        empty_and_experiment(args, ctx, out)
        (outdir / "paper_table.json").write_text(json.dumps(out, indent=1, default=str))
        return
    if not args.skip_stacks:
        empty_and_experiment(args, ctx, out)
        stack_rows(args, ctx, out)
    scene_rows(args, ctx, out)
    (outdir / "paper_table.json").write_text(json.dumps(out, indent=1, default=str))
    write_markdown(out, outdir / "paper_table.md")
    plot(out, outdir / "paper_table.png")
    progress(f"wrote {outdir}/paper_table.md, .json, .png")


if __name__ == "__main__":
    main()
