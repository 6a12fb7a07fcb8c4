"""What antialiasing.merge: adjacent saves and costs: stored fragments, error and time against unmerged samples.

Usage: python benchmarks/aa_merge.py [--out DIR] [--scenes .scenes] [--scene-names dragons ...] [--crease 15 ...]
                                     [--size 1024] [--ref-k 8] [--tile 2048] [--frames 8] [--warmup 2]
                                     [--warmup-s 1.5] [--budget-s 3] [--replot]
Per scene, through the compute rasterizer (which merges; `transparency.raster: compute`, as `auto`
takes on a GPU) in guaca_py.reference.linear_pipeline: presort_lf_et at 1 sample, at 4 samples and
at 4 samples merged (at each --crease limit, antialiasing.merge_crease_deg). Reference and errors
as benchmarks/accuracy_scenes.py's (guaca_py.reference: the exact frame at --ref-k x the resolution,
box filtered; RMSE and edge RMSE in 1/255, FLIP where flip-evaluator is installed); per-pass
medians held at the full SM clock on a GPU, wall time on software rasterizers (no performance
figure). Writes benchmarks/results/<device>/aa_merge/aa_merge.{json,md} and <scene>_crops.png (the
window with the most edge pixels in the reference, at 1 and 4 samples and merged, enlarged).
"""

from __future__ import annotations

import numpy as np

from guaca_py import Renderer
from guaca_py.antialiasing import with_settings
from guaca_py.benchmarking import (
    Progress,
    Results,
    add_reference_args,
    bench_args,
    header,
    measure_point,
    open_device,
    scene_paths,
    timer_of,
)
from guaca_py.reference import edge_pixels, exact_reference, frame_errors, linear_pipeline, srgb
from guaca_py.scene.loader import load_scene


def configs(creases: list[float]) -> list[tuple[str, int, str, float]]:
    """(label, samples, merge, merge_crease_deg): 1 and 4 samples, then 4 merged at each crease limit."""
    out = [("1 sample", 1, "off", 15.0), ("4 samples", 4, "off", 15.0)]
    return out + [(f"4 samples, merged, crease {c:g}°", 4, "adjacent", c) for c in creases]


def run_scene(device, path, args, res: Results, progress: Progress) -> dict:
    """The reference, then each configuration of one scene; its crops picture."""
    scene = load_scene(path)
    ref = exact_reference(device.ctx, scene, args.size, args.size, args.ref_k, args.tile)
    edges = edge_pixels(ref)
    progress.note(f"{path.stem}: reference {args.ref_k}x, edge pixels {edges.mean():.1%}")
    rows, images = [], {}
    for label, samples, merge, crease in configs(args.crease):
        pipeline = with_settings(linear_pipeline(samples, merge=merge), {"merge_crease_deg": crease}, "aa_merge")
        r = Renderer(pipeline, ctx=device.ctx, method="presort_lf_et", method_overrides={"raster": "compute"})
        point = measure_point(
            r, scene, args.size, frames=args.frames, warmup=args.warmup, warmup_s=args.warmup_s, slow_s=args.budget_s
        )
        frame = point.last
        row = {
            "label": label,
            "samples": frame.stats.get("antialiasing", {}).get("samples", samples),
            "merge": merge,
            "merge_crease_deg": crease if merge != "off" else None,
            "ms": point.total_ms,
            "timer": point.timer,
            "clock": point.clock,
            "clock_retries": point.clock_retries,
            "stored": frame.stats["fragments"].get("stored"),
            **frame_errors(frame.linear, ref.image, edges),
            "warnings": frame.stats.get("warnings", []),
        }
        r.release()
        rows.append(row)
        images[label] = frame.linear
        progress.step(
            f"{path.stem} {label:32s} {row['ms']:9.3f} ms  stored {row['stored']:>9}  RMSE {row['rmse_255']:.2f}  "
            f"edge {row['edge_rmse_255']:.2f}"
        )
    crops(res.dir / f"{path.stem}_crops.png", ref.image, ref.k, edges, images, rows)
    return {"scene": path.stem, "size": args.size, "ref_k": args.ref_k, "edge_pixels": int(edges.sum()), "rows": rows}


def crops(path, ref_image, k: int, edges, images: dict, rows: list[dict], side: int = 96, zoom: int = 4) -> None:
    """A picture to look at: the window of `side` px with the most edge pixels, in the reference, at 1 sample,
    at 4 samples and merged (the first crease limit), each enlarged `zoom` times and labelled with its error."""
    from PIL import Image, ImageDraw

    side = min(side, *edges.shape)
    sums = np.pad(edges.astype(np.int64).cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    windows = sums[side:, side:] - sums[:-side, side:] - sums[side:, :-side] + sums[:-side, :-side]
    y, x = np.unravel_index(int(np.argmax(windows)), windows.shape)
    shown = [(f"reference ({k}x{k} supersampled)", ref_image, None)] + [
        (r["label"], images[r["label"]], r) for r in rows[:3]
    ]
    tile, caption = side * zoom, 30
    sheet = Image.new("RGB", (len(shown) * (tile + 8) - 8, tile + caption), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (label, img, row) in enumerate(shown):
        crop = (srgb(img[y : y + side, x : x + side]) * 255 + 0.5).astype(np.uint8)
        sheet.paste(Image.fromarray(crop).resize((tile, tile), Image.NEAREST), (i * (tile + 8), 0))
        text = label if row is None else f"{label}: edge RMSE {row['edge_rmse_255']:.2f}, {row['stored']:,} nodes"
        draw.text((i * (tile + 8) + 2, tile + 8), text, fill=(0, 0, 0))
    path.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(path)


def markdown(rec: dict) -> str:
    """One table per scene, each row against the 1-sample and the unmerged 4-sample row."""
    rows = [r for s in rec["scenes"] for r in s["rows"]]
    out = header("antialiasing.merge: adjacent against unmerged samples", rec["device"], rec["command"], timer_of(rows))
    for s in rec["scenes"]:
        one, four = s["rows"][0], s["rows"][1]
        out += [f"## {s['scene']} ({s['size']}², reference {s['ref_k']}x, {s['edge_pixels']} edge pixels)", ""]
        out += [f"![crops]({s['scene']}_crops.png)", ""]
        out += [
            "| configuration | ms | against 1 sample | SM MHz | stored | against 1 sample | RMSE | edge RMSE | FLIP |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in s["rows"]:
            fl = f"{r['flip']:.4f}" if isinstance(r["flip"], float) else "—"
            mhz = (r.get("clock") or {}).get("sm_clock_mhz_median", "—")
            out.append(
                f"| {r['label']} | {r['ms']:.3f} | {r['ms'] / one['ms']:.2f}x | {mhz} | {r['stored']} | "
                f"{r['stored'] / max(1, one['stored']):.2f}x | {r['rmse_255']:.2f} | {r['edge_rmse_255']:.2f} | {fl} |"
            )
        out.append("")
        for merged in s["rows"][2:]:
            out.append(
                f"- {merged['label']}: {merged['stored'] / max(1, four['stored']):.0%} of the unmerged 4-sample "
                f"fragments; edge RMSE {one['edge_rmse_255'] / merged['edge_rmse_255']:.2f}x lower than 1 sample "
                f"(unmerged: {one['edge_rmse_255'] / four['edge_rmse_255']:.2f}x)."
            )
        out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    """Measure the merge on each scene (or rebuild the table with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=8, scenes=True)
    ap.set_defaults(scene_names=["dragons"])
    add_reference_args(ap)
    ap.add_argument("--budget-s", type=float, default=3.0, help="a slower first frame: measure one frame")
    ap.add_argument("--crease", nargs="*", type=float, default=[15.0], help="merge_crease_deg of the merged rows")
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        rec = res.read_json()
    else:
        device = open_device()
        res = Results(args, device.name, argv)
        paths = scene_paths(args)
        progress = Progress(len(paths) * len(configs(args.crease)))
        scenes = [run_scene(device, path, args, res, progress) for path in paths]
        res.write_json({"scenes": scenes})
        rec = {"device": device.name, "command": res.command, "scenes": scenes}
        device.release()
    res.write_markdown(markdown(rec))
    print(f"wrote {res.dir}/aa_merge.md, .json and the crops", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
