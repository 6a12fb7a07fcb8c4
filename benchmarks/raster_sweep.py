"""Fragments per second against mean triangle size, hardware and compute rasterizer side by side.

Usage: python benchmarks/raster_sweep.py [--out DIR] [--size 1024] [--frames 10] [--warmup 5]
                                         [--areas 0.5 1 2 ...] [--max-triangles 2000000]
                                         [--fragments-per-pixel 4] [--method presort_lf] [--replot]
For each mean triangle area A (px²) a mesh of N = min(max_triangles, fpp·W·H / A) random
triangles of that area is spread over the view at random depths (so about fpp·W·H fragments, as
far as the triangle cap allows), drawn with an unlit alpha-0.5 material. Both rasterizers render
it interleaved frame by frame (warm-up, then medians of the per-pass times, the SM clock sampled
beside; a point measured under 90% of the maximum clock is measured again). Rate = fragments the
A-buffer stored / geometry-pass time. On llvmpipe (wall-clock timers) use a small --size.
Writes benchmarks/results/<device>/raster_sweep/raster_sweep.{json,md,png}.
"""

from __future__ import annotations

import numpy as np

from guaca_py import Renderer
from guaca_py.benchmarking import (
    Progress,
    Results,
    at_full_clock,
    bench_args,
    clock_summary,
    header,
    measure_interleaved,
    open_device,
)
from guaca_py.benchmarking.scenes import triangle_scene
from guaca_py.raster.choice import AUTO_MAX_MEAN_AREA_PX

DEFAULT_AREAS = (0.5, 1, 2, 4, 8, 16, 32, 64, 128, 256, 1024, 4096, 16384)


def projected_area(scene, size: int) -> float:
    """Mean screen area in px² of the scene's triangles (its one node, drawn untransformed)."""
    cam = scene.camera
    mesh = scene.nodes[0].mesh
    p = np.c_[mesh.positions, np.ones(len(mesh.positions))] @ (cam.projection_matrix(1.0) @ cam.view_matrix()).T
    xy = (p[:, :2] / p[:, 3:4] * 0.5 + 0.5) * size
    a, b, c = (xy[mesh.indices.reshape(-1, 3)[:, i]] for i in range(3))
    u, v = b - a, c - a
    return float(np.mean(0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])))


def run(args, device, progress: Progress) -> list[dict]:
    """One row per area: both rasterizers, fresh renderers each (the mesh leaves the GPU with them)."""
    size = args.size
    rows = []
    for area in args.areas:
        count = max(1, min(args.max_triangles, int(args.fragments_per_pixel * size * size / area)))
        scene = triangle_scene(area, count, size)
        renderers = {
            raster: Renderer("exact", ctx=device.ctx, method=args.method, method_overrides={"raster": raster})
            for raster in ("hardware", "compute")
        }
        m, clock, retries = at_full_clock(
            lambda scene=scene, renderers=renderers: measure_interleaved(
                renderers, scene, size, size, args.warmup, args.frames
            )
        )
        row = {"area_px": area, "mean_projected_area_px": projected_area(scene, size), "triangles": count}
        row["clock_retries"] = retries
        row.update(clock_summary(clock.samples) or {})
        for raster, res in m.items():
            st = res.last.stats
            frags = st["fragments"]["stored"]
            ms = res.pass_ms["geometry"]
            row[raster] = {
                "geometry_ms": ms,
                "fragments": frags,
                "gfrag_per_s": frags / (ms * 1e-3) / 1e9 if ms > 0 else None,
                "timer": res.timer,
                "raster": st.get("raster", {}),
            }
        for r in renderers.values():
            r.release()
        rows.append(row)
        hw, cs = row["hardware"], row["compute"]
        progress.step(
            f"{area:>7g} px²: {count:>8} triangles, {cs['fragments']:>9} fragments, hardware {hw['geometry_ms']:9.3f} ms, "
            f"compute {cs['geometry_ms']:9.3f} ms"
        )
    return rows


def markdown(rec: dict) -> str:
    """The table: geometry-pass time and stored fragments per second of both rasterizers per area."""
    out = header(f"Rasterizers against triangle size at {rec['size'][0]}²", rec["device"], rec["command"], rec["timer"])
    out += [
        f"Method `{rec['method']}`; median of {rec['frames']} frames after {rec['warmup']} warm-up, interleaved; "
        f"`raster: auto` takes the compute rasterizer up to a mean of {rec['auto_max_mean_area_px']:g} px².",
        "",
        "| area px² | measured | triangles | fragments | hardware ms | compute ms | hardware G/s | compute G/s "
        "| hardware / compute | SM MHz |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rec["rows"]:
        hw, cs = r["hardware"], r["compute"]
        ratio = hw["geometry_ms"] / cs["geometry_ms"] if cs["geometry_ms"] else float("nan")
        out.append(
            f"| {r['area_px']:g} | {r['mean_projected_area_px']:.2f} | {r['triangles']} | {cs['fragments']} | "
            f"{hw['geometry_ms']:.3f} | {cs['geometry_ms']:.3f} | {hw['gfrag_per_s']:.4g} | {cs['gfrag_per_s']:.4g} | "
            f"{ratio:.2f} | {r.get('sm_clock_mhz_median', '—')} |"
        )
    return "\n".join(out) + "\n"


def chart(rec: dict):
    """A drawing function: fragments per second of both rasterizers against the measured mean triangle area."""

    def draw(plt):
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for raster, style in (("hardware", "o-"), ("compute", "s-")):
            xs = [r["mean_projected_area_px"] for r in rec["rows"]]
            ys = [r[raster]["gfrag_per_s"] for r in rec["rows"]]
            ax.plot(xs, ys, style, label=f"raster: {raster}")
        ax.axvline(rec["auto_max_mean_area_px"], color="grey", ls=":", label="auto threshold")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("mean projected triangle area (px²)")
        ax.set_ylabel("fragments stored per second (G/s)")
        clock = "GPU timer" if rec["timer"] == "gpu" else "wall clock: a software rasterizer, no GPU figure"
        ax.set_title(f"{rec['device']}, {rec['size'][0]}², {rec['method']} ({clock})", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        return fig

    return draw


def main(argv: list[str] | None = None) -> int:
    """Sweep the triangle sizes (or rebuild the table and chart with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=10)
    ap.set_defaults(warmup=5)
    ap.add_argument("--areas", type=float, nargs="*", default=list(DEFAULT_AREAS))
    ap.add_argument("--max-triangles", type=int, default=2_000_000)
    ap.add_argument("--fragments-per-pixel", type=float, default=4.0)
    ap.add_argument(
        "--method", default="presort_lf", help="one-pass A-buffer method (no early termination: all stored)"
    )
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        rec = res.read_json()
    else:
        device = open_device()
        res = Results(args, device.name, argv)
        rows = run(args, device, Progress(len(args.areas)))
        rec = {
            "timer": rows[0]["hardware"]["timer"] if rows else None,
            "size": [args.size, args.size],
            "method": args.method,
            "frames": args.frames,
            "warmup": args.warmup,
            "auto_max_mean_area_px": AUTO_MAX_MEAN_AREA_PX,
            "rows": rows,
        }
        device.release()
    res.finish(rec, markdown, chart)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
