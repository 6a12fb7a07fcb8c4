"""What anti-aliasing costs, pass by pass: the default pipeline at 1 and N samples per scene and path.

Usage: python benchmarks/aa_cost.py [--out DIR] [--scenes .scenes] [--scene-names dragons ...] [--size 1024]
                                   [--samples 1 4] [--raster auto hardware compute/mesh]
                                   [--paths default 32bit] [--method presort_lf] [--warmup-s 1.5] [--frames 8]
For every scene, A-buffer insertion path (`default`: the device's; `32bit`: 64-bit atomics switched
off, so the CAS-linked lists), rasterizer (`transparency.raster`; compute/ORDER also sets
raster_order) and sample count: per-pass
medians held at the full SM clock, stored fragments, and the cost against 1 sample (--method:
another transparency method in the default pipeline). With the compute rasterizer's stage profiler
on (GUACA_RASTER_STAGES=1) it adds the time per stage (the last timed frame of each row).
Writes benchmarks/results/<device>/aa_cost/aa_cost.{json,md}.
"""

from __future__ import annotations

from guaca_py import GuacaError, Renderer, load_pipeline
from guaca_py.antialiasing import with_samples
from guaca_py.benchmarking import (
    Progress,
    Results,
    bench_args,
    header,
    measure_point,
    open_device,
    scene_paths,
    timer_of,
)
from guaca_py.scene.loader import load_scene

PATHS = {"default": (), "32bit": ("atomic_int64",)}  # capabilities switched off per insertion path
STAGES = ("between_draws", "vertex", "order", "setup", "bin", "fine")


def configs(args) -> list[tuple[str, int]]:
    """(raster, samples) of one scene and path."""
    return [(r, n) for r in args.raster for n in args.samples]


def run(args, progress: Progress) -> tuple[str, list[dict]]:
    """Every (path, scene, raster, samples) row; the device's name."""
    rows, name, seen = [], "?", set()
    for path in args.paths:
        device = open_device(PATHS[path])
        name = device.name
        if device.caps.insertion_path in seen:  # a device without 64-bit atomics has one path only
            progress.note(f"insertion path {path}: {device.caps.insertion_path}, measured already")
            progress.total -= len(scene_paths(args)) * len(configs(args))
            device.release()
            continue
        seen.add(device.caps.insertion_path)
        progress.note(f"insertion path {path}: {device.caps.insertion_path}")
        for scene_path in scene_paths(args):
            scene = load_scene(scene_path)
            for raster, n in configs(args):
                row = {"scene": scene_path.stem, "path": device.caps.insertion_path, "rasterizer": raster}
                row.update(samples=n)
                kind, _, order = raster.partition("/")  # compute/ORDER: with that raster_order
                overrides = {"raster": kind, **({"raster_order": order} if order else {})}
                r = None
                try:
                    pipeline = with_samples(load_pipeline("default"), n, "aa_cost")
                    r = Renderer(
                        pipeline,
                        ctx=device.ctx,
                        method=args.method,
                        method_overrides=overrides,
                        restore_host_state=False,
                    )
                    point = measure_point(
                        r, scene, args.size, frames=args.frames, warmup=args.warmup, warmup_s=args.warmup_s
                    )
                    row.update(point.as_dict(), fragments=point.last.stats.get("fragments", {}))
                    row["raster"] = point.last.stats.get("raster")
                except GuacaError as exc:
                    row["skipped"] = str(exc)
                finally:
                    if r is not None:
                        r.release()
                rows.append(row)
                label = f"{scene_path.stem} {row['path']} {raster} x{n}"
                if "skipped" in row:
                    progress.step(f"{label}: skipped ({row['skipped']})")
                    continue
                passes = ", ".join(f"{k} {v:.3f}" for k, v in row["passes_ms"].items())
                mhz = (row["clock"] or {}).get("sm_clock_mhz_median", "—")
                progress.step(
                    f"{label}: {row['total_ms']:8.3f} ms ({passes}) stored {row['fragments'].get('stored')} SM {mhz} MHz"
                )
        device.release()
    return name, rows


def markdown(rec: dict) -> str:
    """A row per configuration, with the cost against the same scene, path and rasterizer at 1 sample."""
    rows = rec["rows"]
    one = {(r["scene"], r["path"], r["rasterizer"]): r for r in rows if r["samples"] == 1 and "skipped" not in r}
    out = header("Anti-aliasing cost, pass by pass", rec["device"], rec["command"], timer_of(rows))
    out += [
        "| scene | path | raster | samples | geometry | composite | total ms | against 1 sample | stored | SM MHz |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        head = f"| {r['scene']} | {r['path']} | {r['rasterizer']} | {r['samples']} |"
        if "skipped" in r:
            out.append(f"{head} skipped: {r['skipped']} | | | | | |")
            continue
        base = one.get((r["scene"], r["path"], r["rasterizer"]))
        ratio = f"{r['total_ms'] / base['total_ms']:.2f}x" if base else "—"
        p = r["passes_ms"]
        clock = (r.get("clock") or {}).get("sm_clock_mhz_median", "—")
        out.append(
            f"{head} {p.get('geometry', 0):.3f} | {p.get('composite', 0):.3f} | {r['total_ms']:.3f} | {ratio} | "
            f"{r['fragments'].get('stored', '—')} | {clock} |"
        )
    stages = [(r, ((r.get("raster") or {}).get("compute") or {}).get("stage_ms")) for r in rows]
    stages = [(r, st) for r, st in stages if st]
    if stages:
        out += ["", "## Compute rasterizer stages (ms, last frame of each row)", ""]
        out += [
            "`between_draws`: from the rasterizer's set-up to the first draw and from each draw's last stage to "
            "the next draw's first; `outside`: the rest of the geometry pass (its clears and G-buffer, "
            "before the rasterizer starts).",
            "",
            "| scene | path | samples | " + " | ".join(STAGES) + " | outside |",
            "|---|---|---|" + "---|" * (len(STAGES) + 1),
        ]
        for r, st in stages:
            cells = " | ".join(f"{st.get(n, 0.0):.3f}" for n in STAGES)
            outside = r["passes_ms"].get("geometry", 0.0) - sum(st.values())
            out.append(f"| {r['scene']} | {r['path']} | {r['samples']} | {cells} | {outside:.3f} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Measure the anti-aliasing cost (or rebuild its table with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=8, scenes=True)
    ap.set_defaults(scene_names=["dragons"])
    ap.add_argument("--samples", nargs="*", type=int, default=[1, 4])
    ap.add_argument("--method", default=None, help="transparency method (default: the default pipeline's)")
    ap.add_argument(
        "--raster", nargs="*", default=["auto"], help="auto, hardware, compute or compute/ORDER (with raster_order)"
    )
    ap.add_argument("--paths", nargs="*", default=["default"], choices=list(PATHS))
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        rec = res.read_json()
    else:
        progress = Progress(len(args.paths) * len(scene_paths(args)) * len(configs(args)))
        name, rows = run(args, progress)
        res = Results(args, name, argv)
        rec = {"rows": rows}
    res.finish(rec, markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
