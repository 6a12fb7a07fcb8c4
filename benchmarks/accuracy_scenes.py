"""Speed against error on real scenes: every method, and the exact default at 1/2/4/8 samples.

Usage: python benchmarks/accuracy_scenes.py OUTDIR --scenes DIR [--size 1024] [--ref-k 8] [--tile 2048]
                                           [--frames 5] [--warmup 2] [--budget-s 3] [--methods ID ...]
                                           [--samples 1 2 4 8] [--scene-names NAME ...] [--replot]
Each scene (DIR/*.yaml) renders through guaca_py.accuracy.linear_pipeline: light culling as in
the default pipeline, no tone mapping or FXAA (linear output), threshold 0.999 for every method, so
exact methods differ from the reference by their aliasing alone. Reference: presort_lf (exact, no
early termination, hardware rasterizer) at --ref-k x the resolution, in tiles of at most --tile px,
box filtered.
Error (linear, clipped to [0, 1], in 1/255): RMSE over all pixels, RMSE over edge pixels (their
k x k sub-pixels span > 0.05: silhouettes, boundaries, intersections), mean FLIP (sRGB-encoded,
when flip-evaluator is installed; computed in --flip-workers processes while the GPU renders on,
as one 1024² FLIP takes seconds of CPU). Time: median of --frames per-pass GPU timer sums after --warmup
(wall time on software rasterizers); a configuration whose first frame exceeds --budget-s is
measured on fewer frames. Writes OUTDIR/<scene>/accuracy.{json,md,png} and OUTDIR/README.md.
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

from gpu_clock import ClockSampler  # noqa: E402

from guaca_py import GuacaError, Renderer  # noqa: E402
from guaca_py.accuracy import edge_pixels, flip, linear_pipeline, rmse_255, supersampled  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.methods import method_class, method_ids  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402

AA_METHOD = "presort_lf_et"  # the exact default, measured at every sample count
REFERENCE_METHOD = "presort_lf"  # exact without early termination


def configs(caps, methods: list[str] | None, samples: list[int]) -> list[tuple[str, str, int, dict]]:
    """(label, method, samples, overrides): every method the device runs at 1 sample (its defaults), and
    the default at each sample count through the hardware rasterizer (coverage masks need it; x1 too,
    so the sample counts compare like for like where `raster: auto` would pick the compute rasterizer)."""
    ids = methods or [m for m in method_ids() if method_class(m).unsupported_reason(caps) is None]
    out = [(m, m, 1, {}) for m in ids]
    out += [(f"{AA_METHOD} hw x{n}", AA_METHOD, n, {"raster": "hardware"}) for n in samples]
    return out


def measure(r: Renderer, scene, size: int, warmup: int, frames: int, budget_s: float) -> tuple[dict, object]:
    """Median per-pass and total ms, and the last frame; fewer frames when one frame exceeds the budget."""
    t0 = time.perf_counter()
    last = r.render(scene, size, size)
    if time.perf_counter() - t0 > budget_s:
        warmup, frames = 0, 1
    for _ in range(max(0, warmup - 1)):
        last = r.render(scene, size, size)
    totals, passes = [], {}
    for _ in range(max(1, frames)):
        last = r.render(scene, size, size)
        for name, p in last.stats["passes"].items():
            passes.setdefault(name, []).append(p["ms"])
        totals.append(sum(p["ms"] for p in last.stats["passes"].values()))
    return {
        "ms": statistics.median(totals),
        "pass_ms": {k: statistics.median(v) for k, v in passes.items()},
        "frames": len(totals),
        "timer": last.stats.get("timer"),
    }, last


def run_scene(ctx, caps, path: Path, args, pool) -> dict:
    """Reference, then every configuration of one scene; the scene's JSON record."""
    scene = load_scene(path)
    size = args.size
    t0 = time.perf_counter()
    # the hardware rasterizer, as for every sample count: one set of coverage rules throughout
    ref_r = Renderer(linear_pipeline(1), ctx=ctx, method=REFERENCE_METHOD, method_overrides={"raster": "hardware"})
    ref = supersampled(ref_r, scene, size, size, args.ref_k, args.tile)
    ref_r.release()
    edges = edge_pixels(ref)
    print(
        f"{path.stem}: reference {args.ref_k}x ({ref.tiles} tiles) {time.perf_counter() - t0:.1f} s, "
        f"edge pixels {edges.mean():.1%}",
        flush=True,
    )
    rows = []
    for label, mid, n, overrides in configs(caps, args.methods, args.samples):
        row = {"label": label, "method": mid, "samples": n, "exact": method_class(mid).exact, "settings": overrides}
        try:
            r = Renderer(linear_pipeline(n), ctx=ctx, method=mid, method_overrides=overrides or None)
        except GuacaError as exc:  # a sample count or method this device refuses: recorded, not fatal
            row["skipped"] = str(exc)
            rows.append(row)
            print(f"  {label}: skipped ({exc})", flush=True)
            continue
        try:
            with ClockSampler() as clock:
                timing, frame = measure(r, scene, size, args.warmup, args.frames, args.budget_s)
            img = frame.linear
            row.update(timing)
            row["samples"] = r.samples
            row["clock"] = clock.summary()
            row["rmse_255"] = rmse_255(img, ref.image)
            row["edge_rmse_255"] = rmse_255(img, ref.image, edges)
            row["flip"] = pool.submit(flip, img, ref.image) if pool is not None else flip(img, ref.image)
            row["fragments"] = frame.stats.get("fragments", {})
            row["raster"] = frame.stats.get("raster", {}).get("why")
            row["memory"] = frame.stats.get("memory", {})
            row["warnings"] = frame.stats.get("warnings", [])
        except GuacaError as exc:
            row["skipped"] = str(exc)
        finally:
            r.release()
        rows.append(row)
        if "skipped" not in row:
            fl = f"  FLIP {row['flip']:.4f}" if isinstance(row["flip"], float) else ""
            print(
                f"  {label:28s} {row['ms']:9.3f} ms  RMSE {row['rmse_255']:6.2f}  edge {row['edge_rmse_255']:6.2f}{fl}",
                flush=True,
            )
    for row in rows:
        if hasattr(row.get("flip"), "result"):
            row["flip"] = row["flip"].result()
    return {
        "scene": path.stem,
        "file": path.name,
        "size": size,
        "reference": {"method": REFERENCE_METHOD, "k": args.ref_k, "tiles": ref.tiles, "edge_tolerance": 0.05},
        "edge_pixels": int(edges.sum()),
        "rows": rows,
    }


def is_aa(row: dict) -> bool:
    """A row of the default's sample-count series."""
    return row["label"].startswith(f"{AA_METHOD} hw x")


def markdown(rec: dict, command: str, device: str) -> str:
    """One scene's table."""
    ref = rec["reference"]
    out = [
        f"# {rec['scene']}: speed against error at {rec['size']}²",
        "",
        f"Device: {device}. Reference: `{ref['method']}` at {ref['k']}x ({ref['tiles']} tiles), box filtered. "
        f"Edge pixels (sub-pixels span > {ref['edge_tolerance']}): {rec['edge_pixels']}.",
        "Error in 1/255 of the linear output clipped to [0, 1]; time: median frame (sum of pass times).",
        "",
        f"Command: `{command}`",
        "",
        "![speed against error](accuracy.png)",
        "",
        "| configuration | exact | samples | frame ms | RMSE | edge RMSE | FLIP | node B | stored |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rec["rows"]:
        if "skipped" in r:
            out.append(f"| {r['label']} | | {r['samples']} | skipped: {r['skipped']} | | | | | |")
            continue
        fl = f"{r['flip']:.4f}" if r.get("flip") is not None else "—"
        node = r["memory"].get("abuffer_node_bytes", "—")
        stored = r["fragments"].get("stored", "—")
        out.append(
            f"| {r['label']} | {'yes' if r['exact'] else 'no'} | {r['samples']} | {r['ms']:.3f} | "
            f"{r['rmse_255']:.2f} | {r['edge_rmse_255']:.2f} | {fl} | {node} | {stored} |"
        )
    aa = {r["samples"]: r for r in rec["rows"] if is_aa(r) and "skipped" not in r}
    auto = next((r for r in rec["rows"] if r["label"] == AA_METHOD and "skipped" not in r), None)
    if 1 in aa and 4 in aa:
        one, four = aa[1], aa[4]
        out += [
            "",
            f"`{AA_METHOD}` 4 samples against 1 (both through the hardware rasterizer): edge RMSE "
            f"{one['edge_rmse_255'] / four['edge_rmse_255']:.2f}x lower (target >= 2), frame time "
            f"{four['ms'] / one['ms']:.2f}x (target <= 1.6)"
            + (f"; against the 1-sample default (`raster: auto`) {four['ms'] / auto['ms']:.2f}x." if auto else "."),
        ]
    return "\n".join(out) + "\n"


def chart(rec: dict, path: Path) -> None:
    """Frame time against RMSE and edge RMSE; the default's sample counts joined by a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
        ax.set_xlabel("frame time (ms, median)")
        ax.set_ylabel("error against the supersampled exact frame (1/255)")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    ref = rec["reference"]
    fig.suptitle(
        f"{rec['scene']} at {rec['size']}²: reference {ref['method']} {ref['k']}x{ref['k']} "
        f"(blue: exact, red: approximate, green: {AA_METHOD}, hardware raster, 1/2/4/8 samples)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scenes", type=Path, required=True, help="folder of scene YAMLs (e.g. ../shared/scenes)")
    ap.add_argument("--scene-names", nargs="*", help="only these scenes (file stems)")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--ref-k", type=int, default=8, help="reference supersampling factor (4 or 8)")
    ap.add_argument("--tile", type=int, default=2048, help="largest reference tile side in px")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--budget-s", type=float, default=3.0, help="a slower first frame: measure one frame")
    ap.add_argument("--methods", nargs="*", help="methods at 1 sample (default: every method the device runs)")
    ap.add_argument("--samples", nargs="*", type=int, default=[1, 2, 4, 8], help=f"sample counts of {AA_METHOD}")
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
        device = caps.renderer
        scenes = sorted(args.scenes.glob("*.yaml"))
        if args.scene_names:
            scenes = [p for p in scenes if p.stem in args.scene_names]
        for path in scenes:
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
        index.append(f"- [{rec['scene']}]({rec['scene']}/accuracy.md) ({rec['size']}², {rec['device']})")
    (args.out / "README.md").write_text("\n".join(index) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
