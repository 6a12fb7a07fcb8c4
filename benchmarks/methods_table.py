"""Every transparency method the device runs, side by side: time per stage, passes, memory, error.

Usage: python benchmarks/methods_table.py [--out DIR] [--size 1024] [--frames 10] [--warmup 5]
                                          [--timing isolated|interleaved] [--methods ID ...] [--ref-size 192] [--replot]
Timing: the demo scene through pipelines/default.yaml (median of --frames after --warmup), each method
in its own `guaca render` process as a user runs it (isolated, the SM clock sampled and a throttled
method measured again), or all in this process interleaved frame by frame (interleaved).
Error: (a) the demo scene, lit, linear output of pipelines/exact.yaml, against presort_lf (exact,
itself verified against the CPU reference) on the same device; (b) an unlit layered scene (16
layers, shuffled submission) against the float64 CPU reference (guaca_py.reference), non-edge
pixels. Errors are in 1/255. Writes benchmarks/results/<device>/methods_table/methods_table.{json,md,png}.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

from guaca_py import GuacaError, Renderer, UnsupportedMethodError
from guaca_py.benchmarking import (
    ClockSampler,
    Progress,
    Results,
    at_full_clock,
    bench_args,
    clock_summary,
    measure_interleaved,
    open_device,
    time_label,
    timer_sentence,
)
from guaca_py.methods import method_class, method_ids
from guaca_py.reference import compare, layered_quads_scene, reference_of, rmse_max_255
from guaca_py.scene.loader import demo_scene

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    """Time and check every method (or rebuild the table and chart with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=10)
    ap.set_defaults(warmup=5)
    ap.add_argument("--ref-size", type=int, default=192, help="size of the layered scene against the CPU reference")
    ap.add_argument(
        "--timing",
        choices=("isolated", "interleaved"),
        default="isolated",
        help="isolated: each method in its own `guaca render` process, as a user runs it; "
        "interleaved: one process, one frame of each method per round",
    )
    ap.add_argument("--methods", nargs="*")
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        data = res.read_json()
    else:
        device = open_device()
        res = Results(args, device.name, argv)
        data = run(device, args, res.command)
    page = res.finish(
        data,
        lambda d: table(d["rows"], d["meta"], d["command"]),
        lambda d: chart(d["rows"], d["meta"]),
    )
    print(page)
    return 0


def run(device, args, command: str) -> dict:
    """Timing first (before the CPU-heavy error phase), then the errors; the record."""
    ctx = device.ctx
    demo = demo_scene()
    layered = layered_quads_scene(n_layers=16, order="shuffled", seed=11)
    rs = args.ref_size
    ref_img, ref_mask, _ = reference_of(layered, rs, rs)
    exact_r = Renderer("exact", ctx=ctx, method="presort_lf")
    exact_demo = exact_r.render(demo, args.size, args.size).linear
    exact_r.release()
    rows, runnable = [], []
    for mid in args.methods or method_ids():
        row = {"method": mid, "exact": method_class(mid).exact}
        rows.append(row)
        try:
            Renderer("exact", ctx=ctx, method=mid).release()
        except UnsupportedMethodError as exc:
            row["skipped"] = str(exc)
            print(f"{mid:<26} skipped: {exc}", flush=True)
        else:
            runnable.append(mid)
    progress = Progress(2 * len(runnable))
    timing = time_isolated if args.timing == "isolated" else time_interleaved
    results, clock_samples = timing(runnable, ctx, demo, args, progress)
    for row in rows:
        row.update(results.get(row["method"], {}))
    for row in rows:
        mid = row["method"]
        if "pass_ms" not in row:
            continue
        try:
            r = Renderer("exact", ctx=ctx, method=mid)
            row["demo_rmse_255"], row["demo_max_255"] = rmse_max_255(
                r.render(demo, args.size, args.size).linear, exact_demo
            )
            e = compare(r.render(layered, rs, rs).image, ref_img, ref_mask)
            row["ref_rmse_255"], row["ref_max_255"] = e["rmse_255"], e["max_abs_255"]
            r.release()
        except GuacaError as exc:
            row["failed"] = str(exc)
            del row["pass_ms"]
        progress.step(
            f"{mid:<26} "
            + (
                f"failed: {row['failed']}"
                if "failed" in row
                else f"{row['total_ms']:8.3f} ms  passes {row['geometry_passes']}  "
                f"err(demo) {row['demo_rmse_255']:.3f}/{row['demo_max_255']:.1f}  "
                f"err(ref) {row['ref_rmse_255']:.3f}/{row['ref_max_255']:.1f}"
            )
        )
    post = [sum(v for k, v in r["pass_ms"].items() if k in ("tone_mapping", "fxaa")) for r in rows if "pass_ms" in r]
    meta = {
        "device": device.name,
        "size": args.size,
        "frames": args.frames,
        "warmup": args.warmup,
        "ref_size": rs,
        "insertion_path": device.caps.insertion_path,
        "timing": args.timing,
        "timer": next((r["timer"] for r in rows if "timer" in r), None),
        # identical post passes in every row: their spread shows how steady the clock was
        "post_ms_min": min(post, default=0.0),
        "post_ms_max": max(post, default=0.0),
        **(clock_summary(clock_samples) or {}),
    }
    return {"meta": meta, "rows": rows}


def _row_from_stats(s: dict, pass_ms: dict, total_ms: float) -> dict:
    """The timing columns of a row from a frame's stats and the measured per-pass medians."""
    return dict(
        pass_ms=pass_ms,
        total_ms=total_ms,
        timer=s.get("timer", "?"),
        geometry_passes=s.get("geometry_passes", 1),
        fragments=s.get("fragments", {}),
        memory=s.get("memory", {}),
        warnings=s.get("warnings", []),
    )


def time_interleaved(mids: list[str], ctx, scene, args, progress: Progress) -> tuple[dict[str, dict], list[int]]:
    """All methods in this process, one frame of each per round: clock changes hit all alike."""
    out, timed = {}, {}
    for mid in mids:
        try:
            timed[mid] = Renderer("default", ctx=ctx, method=mid)
        except GuacaError as exc:
            out[mid] = {"failed": str(exc)}
    try:
        with ClockSampler() as clock:
            ms = measure_interleaved(timed, scene, args.size, args.size, args.warmup, args.frames)
    except GuacaError as exc:
        raise SystemExit(f"timing failed: {exc}") from exc
    for mid, m in ms.items():
        out[mid] = _row_from_stats(m.last.stats, m.pass_ms, m.total_ms)
        timed[mid].release()
        progress.step(f"{mid:<26} timed: {out[mid]['total_ms']:.3f} ms")
    return out, clock.samples


def time_isolated(mids: list[str], ctx, scene, args, progress: Progress) -> tuple[dict[str, dict], list[int]]:
    """Each method in a fresh `guaca render --warmup W --frames F` process (the demo scene), with its SM clock."""
    out, samples = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for mid in mids:
            stats_path = Path(tmp) / f"{mid}.json"
            cmd = [
                sys.executable,
                "-m",
                "guaca_py",
                "render",
                "--method",
                mid,
                "--width",
                str(args.size),
                "--height",
                str(args.size),
                "--warmup",
                str(args.warmup),
                "--frames",
                str(args.frames),
                "--out",
                str(Path(tmp) / f"{mid}.png"),
                "--stats",
                str(stats_path),
            ]
            proc, clock, retries = at_full_clock(
                lambda cmd=cmd: subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT),
                valid=lambda p: p.returncode == 0,
            )
            if proc.returncode != 0:
                out[mid] = {"failed": " ".join((proc.stderr or proc.stdout).strip().splitlines()[-1:])}
                progress.step(f"{mid:<26} failed: {out[mid]['failed']}")
                continue
            s = json.loads(stats_path.read_text())
            pass_ms = {k: v["ms"] for k, v in s["passes"].items()}
            out[mid] = _row_from_stats(s, pass_ms, sum(pass_ms.values()))
            samples += clock.samples
            if clock.summary():
                out[mid]["sm_clock_mhz_median"] = clock.summary()["sm_clock_mhz_median"]
                out[mid]["clock_retries"] = retries
            progress.step(f"{mid:<26} timed: {out[mid]['total_ms']:.3f} ms")
    return out, samples


def _mem_alloc_used(mem: dict) -> tuple[int, int]:
    """Bytes allocated and bytes the frame used; a buffer without a `_used` figure counts as full."""
    alloc = used = 0
    for k, v in mem.items():
        if k.endswith("_used") or k.endswith("node_bytes"):
            continue
        alloc += v
        used += mem.get(k + "_used", v)
    return alloc, used


def table(rows: list[dict], meta: dict, command: str | None) -> str:
    """Markdown table of the measured rows."""
    how = {
        "isolated": "each method in its own `guaca render` process",
        "interleaved": "methods interleaved frame by frame",
    }.get(meta.get("timing", "interleaved"))
    clocks = any("sm_clock_mhz_median" in r for r in rows)
    out = [
        f"Device: {meta['device']} · {meta['size']}×{meta['size']} demo scene · median of {meta['frames']} "
        f"frames after {meta['warmup']} warm-up, {how} · post passes (identical in every row) "
        f"{meta['post_ms_min']:.3f}–{meta['post_ms_max']:.3f} ms"
        + (
            f" · SM clock while timing {meta['sm_clock_mhz_median']:.0f} MHz median "
            f"({meta['sm_clock_mhz_min']}–{meta['sm_clock_mhz_max']})"
            if "sm_clock_mhz_median" in meta
            else ""
        )
        + " · errors in 1/255 (RMSE / max)",
        "",
        timer_sentence(meta.get("timer", "gpu")),
        "",
        f"Command: `{command}`",
        "",
        "Geometry ms is the G-buffer pass plus any pass that stores fragments; peeling and blending methods "
        "draw their transparent geometry inside the composite pass, so compare totals.",
        "",
        "| method | kind | geometry ms | lights ms | composite ms | post ms | total ms | geo passes | "
        "memory MiB alloc / used | err demo vs exact | err unlit vs CPU ref |" + (" SM MHz |" if clocks else ""),
        "|---|---|---|---|---|---|---|---|---|---|---|" + ("---|" if clocks else ""),
    ]
    for r in rows:
        if "pass_ms" not in r:
            out.append(
                f"| {r['method']} | {'exact' if r['exact'] else 'approx'} | "
                + " | ".join(["—"] * 8)
                + f" | {r.get('skipped') or r.get('failed')} |"
                + (" |" if clocks else "")
            )
            continue
        p = r["pass_ms"]
        post = sum(v for k, v in p.items() if k not in ("geometry", "light_culling", "composite"))
        alloc, used = _mem_alloc_used(r["memory"])
        out.append(
            f"| {r['method']} | {'exact' if r['exact'] else 'approx'} | {p.get('geometry', 0):.3f} | "
            f"{p.get('light_culling', 0):.3f} | {p.get('composite', 0):.3f} | {post:.3f} | {r['total_ms']:.3f} | "
            f"{r['geometry_passes']} | {alloc / 2**20:.1f} / {used / 2**20:.1f} | "
            f"{r['demo_rmse_255']:.2f} / {r['demo_max_255']:.0f} | {r['ref_rmse_255']:.2f} / {r['ref_max_255']:.0f} |"
            + (f" {r['sm_clock_mhz_median']:.0f} |" if "sm_clock_mhz_median" in r else " — |" if clocks else "")
        )
    return "\n".join(out) + "\n"


def chart(rows: list[dict], meta: dict):
    """A drawing function: time per stage for each method, and frame time against error."""
    return lambda plt: _draw(plt, rows, meta)


def _draw(plt, rows: list[dict], meta: dict):
    """The two panels of chart()."""
    timer = meta.get("timer", "gpu")
    done = sorted((r for r in rows if "pass_ms" in r), key=lambda r: r["total_ms"])
    fig, (bars, scat) = plt.subplots(1, 2, figsize=(14, 6.5), gridspec_kw={"width_ratios": [1, 1.15]})
    stages = [
        ("geometry", "tab:blue"),
        ("light_culling", "tab:olive"),
        ("composite", "tab:orange"),
        ("post", "tab:gray"),
    ]
    y = range(len(done))
    left = [0.0] * len(done)
    for stage, color in stages:
        w = [
            sum(v for k, v in r["pass_ms"].items() if k not in ("geometry", "light_culling", "composite"))
            if stage == "post"
            else r["pass_ms"].get(stage, 0.0)
            for r in done
        ]
        bars.barh(y, w, left=left, color=color, label=stage)
        left = [a + b for a, b in zip(left, w)]
    bars.set_yticks(
        list(y), [f"{r['method']} ({r['geometry_passes']})" + ("" if r["exact"] else " ≈") for r in done], fontsize=8
    )
    bars.invert_yaxis()
    bars.set_xlabel(time_label(timer, "ms per frame (median)") + "; label: method (geometry passes), ≈ approximate")
    bars.legend(fontsize=8, loc="upper right")
    bars.set_title("Time per stage (peeling and blending draw inside composite)", fontsize=10)
    # y: lit demo error against the exact A-buffer; exact methods sit at the float floor
    floor = 0.01
    for i, r in enumerate(r for r in done if not r["exact"]):
        # alternate label sides: approximate methods often land close together
        err = max(r["demo_rmse_255"], floor)
        scat.annotate(
            f"{r['method']} (max {r['demo_max_255']:.0f})",
            (r["total_ms"], err),
            fontsize=8,
            xytext=(5, 5 if i % 2 else -12),
            textcoords="offset points",
        )
    for r in done:
        scat.scatter(
            r["total_ms"],
            max(r["demo_rmse_255"], floor),
            marker="o" if r["exact"] else "^",
            s=36,
            color="tab:blue" if r["exact"] else "tab:red",
        )
    exact = [r for r in done if r["exact"]]
    if exact:
        worst = max(r["demo_rmse_255"] for r in exact)
        scat.annotate(
            f"{len(exact)} exact methods, RMSE ≤ {worst:.3f}",
            (min(r["total_ms"] for r in exact), floor),
            fontsize=8,
            xytext=(0, -14),
            textcoords="offset points",
            color="tab:blue",
        )
    scat.set_xscale("log")
    scat.set_yscale("log")
    scat.set_ylim(floor / 3, 100)
    scat.set_xlabel(time_label(timer, "ms per frame (median, log)"))
    scat.set_ylabel(f"RMSE vs exact, 1/255 (lit demo, linear; floor {floor})")
    scat.set_title("Speed against accuracy (○ exact, △ approximate)", fontsize=10)
    fig.suptitle(f"Transparency methods, demo scene {meta['size']}², {meta['device']}", fontsize=11)
    fig.tight_layout()
    return fig


if __name__ == "__main__":
    raise SystemExit(main())
