"""Fragments per second against mean triangle size, hardware and compute rasterizer side by side.

Usage: python benchmarks/raster_sweep.py OUTDIR [--size 1024] [--frames 10] [--warmup 5]
                                         [--areas 0.5 1 2 ...] [--max-triangles 2000000]
                                         [--fragments-per-pixel 4] [--method presort_lf]
For each mean triangle area A (px²) a mesh of N = min(max_triangles, fpp·W·H / A) random
triangles of that area is spread over the view at random depths (so about fpp·W·H fragments, as
far as the triangle cap allows), drawn with an unlit alpha-0.5 material. Both rasterizers render
it interleaved frame by frame (warm-up, then medians of GPU timer queries per pass, the SM clock
sampled beside; a point measured under 90% of the maximum clock is measured again). Rate =
fragments the A-buffer stored / geometry-pass time. Writes OUTDIR/raster_sweep.json and
raster_sweep.png and prints the table. On llvmpipe (wall-clock timers) use a small --size.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from gpu_clock import at_full_clock, clock_summary  # noqa: E402

from guaca_py import Renderer  # noqa: E402
from guaca_py.benchmarking import measure_interleaved  # noqa: E402
from guaca_py.raster.choice import AUTO_MAX_MEAN_AREA_PX, mean_projected_area  # noqa: E402
from guaca_py.raster.compute_raster import MEDIUM_AREA, SMALL_AREA, TILE  # noqa: E402
from guaca_py.scene.graph import Camera, MaterialInstance, MeshData, Node, Scene  # noqa: E402

DEFAULT_AREAS = (0.5, 1, 2, 4, 8, 16, 32, 64, 128, 256, 1024, 4096, 16384)
EYE_Z, FOV_Y = 5.0, 50.0


def triangle_scene(area_px: float, count: int, size: int, seed: int = 0) -> Scene:
    """`count` random triangles of about `area_px` px² each on screen, spread over a square view."""
    rng = np.random.default_rng(seed)
    depth = EYE_Z - rng.uniform(-0.5, 0.5, count)  # distance to the eye
    px = 2.0 * depth * math.tan(math.radians(FOV_Y / 2)) / size  # world size of a pixel there
    # a triangle of random shape (aspect up to 4:1) and orientation, scaled to the area
    ang = rng.uniform(0, 2 * np.pi, count)
    aspect = rng.uniform(1.0, 4.0, count)
    base = np.sqrt(2.0 * area_px * aspect) * px
    height = 2.0 * area_px * px * px / base
    apex = rng.uniform(-0.5, 0.5, count) * base
    local = np.stack(
        [
            np.stack([-base / 2, np.zeros(count)], 1),
            np.stack([base / 2, np.zeros(count)], 1),
            np.stack([apex, height], 1),
        ],
        axis=1,
    )  # (count, 3, 2), counter-clockwise
    rot = np.stack([np.stack([np.cos(ang), -np.sin(ang)], 1), np.stack([np.sin(ang), np.cos(ang)], 1)], 1)
    xy = np.einsum("nij,nkj->nki", rot, local)
    centre = rng.uniform(-0.5, 0.5, (count, 1, 2)) * (depth * 2.0 * math.tan(math.radians(FOV_Y / 2)))[:, None, None]
    z = (EYE_Z - depth)[:, None, None] * np.ones((count, 3, 1))
    pos = np.concatenate([xy + centre, z], axis=2).reshape(-1, 3).astype(np.float32)
    mesh = MeshData(
        pos,
        np.tile(np.float32([0, 0, 1]), (len(pos), 1)),
        np.zeros((len(pos), 2), np.float32),
        np.arange(len(pos), dtype=np.uint32).reshape(-1, 3),
        f"triangles_{area_px:g}px",
    )
    node = Node("triangles", mesh=mesh, material=MaterialInstance("unlit", {"color": [0.8, 0.5, 0.2], "alpha": 0.5}))
    cam = Camera(position=(0, 0, EYE_Z), target=(0, 0, 0), up=(0, 1, 0), fov_y=FOV_Y, near=0.1, far=100)
    return Scene(camera=cam, background=(0.0, 0.0, 0.0), nodes=[node])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--areas", type=float, nargs="*", default=list(DEFAULT_AREAS))
    ap.add_argument("--max-triangles", type=int, default=2_000_000)
    ap.add_argument("--fragments-per-pixel", type=float, default=4.0)
    ap.add_argument(
        "--method", default="presort_lf", help="one-pass A-buffer method (no early termination: all stored)"
    )
    ap.add_argument("--tile", type=int, default=TILE, help="tile edge of the compute large-triangle path")
    ap.add_argument("--small-area", type=int, default=SMALL_AREA, help="largest box one compute thread rasterizes")
    ap.add_argument("--medium-area", type=int, default=MEDIUM_AREA, help="largest box one workgroup rasterizes untiled")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    w = h = args.size
    hardware = Renderer("exact", method=args.method, method_overrides={"raster": "hardware"})
    compute = Renderer("exact", ctx=hardware.ctx, method=args.method, method_overrides={"raster": "compute"})
    cr = compute.raster.compute
    cr.tile, cr.small_area, cr.medium_area = args.tile, args.small_area, args.medium_area
    renderers = {"hardware": hardware, "compute": compute}
    caps = renderers["hardware"].caps
    rows = []
    print(f"device: {caps.gl_renderer}; {w}x{h}, method {args.method}, median of {args.frames} after {args.warmup}")
    print(
        f"{'area px²':>9} {'measured':>9} {'triangles':>10} {'fragments':>11} "
        f"{'hw ms':>9} {'cs ms':>9} {'hw Gfrag/s':>11} {'cs Gfrag/s':>11} {'cs/hw':>6}"
    )
    for area in args.areas:
        count = max(1, min(args.max_triangles, int(args.fragments_per_pixel * w * h / area)))
        scene = triangle_scene(area, count, args.size)
        node = scene.nodes[0]
        cam = scene.camera
        vp = cam.projection_matrix(w / h) @ cam.view_matrix()
        measured = mean_projected_area(node.mesh, np.eye(4), vp, w, h)

        def run(scene=scene):
            return measure_interleaved(renderers, scene, w, h, args.warmup, args.frames)

        m, clock, retries = at_full_clock(run)
        row = {"area_px": area, "mean_projected_area_px": measured, "triangles": count, "clock_retries": retries}
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
        rows.append(row)
        hw, cs = row["hardware"], row["compute"]
        ratio = hw["geometry_ms"] / cs["geometry_ms"] if cs["geometry_ms"] else float("nan")
        print(
            f"{area:>9g} {measured:>9.2f} {count:>10} {cs['fragments']:>11} {hw['geometry_ms']:>9.3f} "
            f"{cs['geometry_ms']:>9.3f} {hw['gfrag_per_s']:>11.4g} {cs['gfrag_per_s']:>11.4g} {ratio:>6.2f}"
        )
        scene.nodes.clear()
        for r in renderers.values():
            r.meshes.release()  # one mesh at a time on the GPU
    result = {
        "device": caps.gl_renderer,
        "timer": rows[0]["hardware"]["timer"] if rows else None,
        "size": [w, h],
        "method": args.method,
        "frames": args.frames,
        "warmup": args.warmup,
        "auto_max_mean_area_px": AUTO_MAX_MEAN_AREA_PX,
        "tile": args.tile,
        "small_area": args.small_area,
        "medium_area": args.medium_area,
        "rows": rows,
    }
    (args.out / "raster_sweep.json").write_text(json.dumps(result, indent=2))
    plot(result, args.out / "raster_sweep.png")
    print(f"wrote {args.out / 'raster_sweep.json'} and {args.out / 'raster_sweep.png'}")
    for r in reversed(renderers.values()):  # the first made the context the others share
        r.release()
    return 0


def plot(result: dict, path: Path) -> None:
    """Fragments per second of both rasterizers against the measured mean triangle area."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for raster, style in (("hardware", "o-"), ("compute", "s-")):
        xs = [r["mean_projected_area_px"] for r in result["rows"]]
        ys = [r[raster]["gfrag_per_s"] for r in result["rows"]]
        ax.plot(xs, ys, style, label=f"raster: {raster}")
    ax.axvline(result["auto_max_mean_area_px"], color="grey", ls=":", label="auto threshold")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("mean projected triangle area (px²)")
    ax.set_ylabel("fragments stored per second (G/s)")
    timer = "GPU timer" if result["timer"] == "gpu" else "wall clock"
    ax.set_title(f"{result['device']}, {result['size'][0]}², {result['method']} ({timer})", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
