"""What anti-aliasing costs, pass by pass: the default pipeline at 1 and N samples per scene and path.

Usage: python benchmarks/aa_cost.py OUTDIR --scenes DIR [--scene-names NAME ...] [--size 1024]
                                   [--samples 1 4] [--merge off adjacent]
                                   [--raster auto hardware compute/mesh] [--paths default 32bit]
                                   [--warmup-s 1.5] [--frames 8] [--small-area 128 32]
                                   [--small-fragments 8 1e9] [--method presort_lf]
For every scene, rasterizer (`transparency.raster`) and A-buffer insertion path (`default`: the
device's, `32bit`: 64-bit atomics switched off, so the CAS-linked lists), the default pipeline at
each sample count: per-pass GPU medians after a warm-up at the maximum SM clock (paper_table.py's
timing), stored fragments, and each count's cost against 1 sample (--method: another transparency
method in that pipeline). Writes OUTDIR/aa_cost.{json,md}.
With GUACA_RASTER_STAGES=1 in the environment it adds the compute rasterizer's time per stage
(vertex, order, setup, bin, fine; the last frame of each row, which waits for its timestamps).
--small-area and --small-fragments take the compute rasterizer's one-thread bounds (a triangle
whose candidate box holds up to that many pixels and which covers up to that many px² is
rasterized by one thread, others by a workgroup) through several values: each pair is a
rasterizer column `RASTER sN fM`.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from paper_table import progress, time_frames  # noqa: E402

from guaca_py import GuacaError, Renderer  # noqa: E402
from guaca_py.antialiasing import with_settings  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.pipeline.config import load_pipeline  # noqa: E402
from guaca_py.raster.compute_raster import SMALL_AREA, SMALL_FRAGMENTS  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402

PATHS = {"default": (), "32bit": ("atomic_int64",)}  # capabilities switched off per insertion path


def run(args) -> list[dict]:
    """Every (path, scene, raster, samples) row."""
    rows = []
    for path in args.paths:
        ctx, caps = create_context(None, PATHS[path])
        progress(f"insertion path {path}: {caps.insertion_path}")
        for name in args.scene_names:
            scene = load_scene(args.scenes / f"{name}.yaml")
            bounds = [(a, f) for a in args.small_area for f in args.small_fragments]
            for raster, (small, fragments) in [(r, b) for r in args.raster for b in bounds]:
                label = raster if bounds == [(SMALL_AREA, SMALL_FRAGMENTS)] else f"{raster} s{small} f{fragments:g}"
                for n, merge in [(n, m) for n in args.samples for m in args.merge if n > 1 or m == "off"]:
                    row = {"scene": name, "path": caps.insertion_path, "rasterizer": label, "samples": n}
                    row["merge"] = merge
                    try:
                        kind, _, order = raster.partition("/")  # compute/ORDER: with that raster_order
                        overrides = {"raster": kind, **({"raster_order": order} if order else {})}
                        r = Renderer(
                            with_settings(load_pipeline("default"), {"samples": n, "merge": merge}, "aa_cost"),
                            ctx=ctx,
                            method=args.method,
                            method_overrides=overrides,
                            restore_host_state=False,
                        )
                        r.raster.compute.small_area = small
                        r.raster.compute.small_fragments = fragments
                        row.update(time_frames(r, scene, args.size, args.warmup_s, args.frames))
                        r.release()
                    except GuacaError as exc:
                        row["skipped"] = str(exc)
                    rows.append(row)
                    if "skipped" in row:
                        progress(f"  {name} {label} x{n}: skipped ({row['skipped']})")
                        continue
                    passes = ", ".join(f"{k} {v:.3f}" for k, v in row["passes_ms"].items())
                    progress(
                        f"  {name:20s} {caps.insertion_path} {label:8s} x{n}{' merged' if merge != 'off' else ''}: {row['total_ms']:8.3f} ms "
                        f"({passes}) stored {row['fragments'].get('stored')} clock {row['clock']}"
                    )
        ctx.release()
    return rows


def markdown(rows: list[dict], command: str) -> str:
    """A table per row, with the cost against the same scene, path and rasterizer at 1 sample."""
    one = {(r["scene"], r["path"], r["rasterizer"]): r for r in rows if r["samples"] == 1 and "skipped" not in r}
    out = [
        "# Anti-aliasing cost, pass by pass",
        "",
        f"Command: `{command}`",
        "",
        "| scene | path | raster | samples | geometry | composite | total GPU ms | against 1 sample | stored | SM MHz |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        merged = " merged" if r.get("merge", "off") != "off" else ""
        head = f"| {r['scene']} | {r['path']} | {r['rasterizer']} | {r['samples']}{merged} |"
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
    stages = [(r, (r.get("raster") or {}).get("compute", {}).get("stage_ms")) for r in rows]
    stages = [(r, st) for r, st in stages if st]
    if stages:
        names = ("between_draws", "vertex", "order", "setup", "bin", "fine")
        out += ["", "## Compute rasterizer stages (GPU ms, last frame of each row)", ""]
        out += [
            "`between_draws`: from the rasterizer's set-up to the first draw and from each draw's last stage to "
            "the next draw's first; `outside`: the rest of the geometry pass (its clears and G-buffer, "
            "before the rasterizer starts).",
            "",
        ]
        out += [
            "| scene | path | samples | " + " | ".join(names) + " | outside |",
            "|---|---|---|" + "---|" * (len(names) + 1),
        ]
        for r, st in stages:
            cells = " | ".join(f"{st.get(n, 0.0):.3f}" for n in names)
            outside = r["passes_ms"].get("geometry", 0.0) - sum(st.values())
            out.append(f"| {r['scene']} | {r['path']} | {r['samples']} | {cells} | {outside:.3f} |")
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scenes", type=Path, required=True)
    ap.add_argument("--scene-names", nargs="*", default=["dragons"])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--samples", nargs="*", type=int, default=[1, 4])
    ap.add_argument("--method", default=None, help="transparency method (default: the default pipeline's)")
    ap.add_argument(
        "--raster",
        nargs="*",
        default=["auto"],
        help="auto, hardware, compute or compute/ORDER (with raster_order ORDER)",
    )
    ap.add_argument("--paths", nargs="*", default=["default"], choices=list(PATHS))
    ap.add_argument(
        "--merge", nargs="*", default=["off"], choices=["off", "adjacent"], help="antialiasing.merge at N > 1 samples"
    )
    ap.add_argument("--small-area", nargs="*", type=int, default=[SMALL_AREA], help="one-thread box bounds (px)")
    ap.add_argument(
        "--small-fragments", nargs="*", type=float, default=[SMALL_FRAGMENTS], help="one-thread area bounds (px²)"
    )
    ap.add_argument("--warmup-s", type=float, default=1.5)
    ap.add_argument("--frames", type=int, default=8)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = run(args)
    command = "python benchmarks/aa_cost.py " + shlex.join(argv if argv is not None else sys.argv[1:])
    (args.out / "aa_cost.json").write_text(json.dumps({"command": command, "rows": rows}, indent=1, default=str))
    (args.out / "aa_cost.md").write_text(markdown(rows, command))
    progress(f"wrote {args.out}/aa_cost.md, .json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
