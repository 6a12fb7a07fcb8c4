"""What antialiasing.merge: adjacent saves and costs: stored fragments, error and time against unmerged samples.

Usage: python benchmarks/aa_merge.py OUTDIR --scenes DIR [--scene-names dragons ...] [--crease 15 ...]
                                     [and benchmarks/accuracy_scenes.py's --size, --ref-k, --tile,
                                      --frames, --warmup, --warmup-s, --budget-s]
Per scene, through the compute rasterizer (which merges; `transparency.raster: compute`, as `auto`
takes on a GPU) in guaca_py.accuracy.linear_pipeline: presort_lf_et at 1 sample, at 4 samples and
at 4 samples merged (at each --crease limit, antialiasing.merge_crease_deg). Reference, errors and
timing are benchmarks/accuracy_scenes.py's (`reference`, `errors`, `measure`: the exact frame at
--ref-k x the resolution, box filtered; RMSE and edge RMSE in 1/255, FLIP where flip-evaluator is
installed; per-pass medians held at the maximum SM clock on a GPU, wall time on software
rasterizers, which is no performance figure). Writes OUTDIR/aa_merge.{json,md} and OUTDIR/<scene>_crops.png (the window with the
most edge pixels in the reference, at 1 and 4 samples and merged, enlarged).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from accuracy_scenes import add_common_args, errors, measure, reference, scene_paths  # noqa: E402
from paper_table import progress  # noqa: E402

from guaca_py import Renderer  # noqa: E402
from guaca_py.accuracy import linear_pipeline  # noqa: E402
from guaca_py.antialiasing import with_settings  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def configs(creases: list[float]) -> list[tuple[str, int, str, float]]:
    """(label, samples, merge, merge_crease_deg): 1 and 4 samples, then 4 merged at each crease limit."""
    out = [("1 sample", 1, "off", 15.0), ("4 samples", 4, "off", 15.0)]
    return out + [(f"4 samples, merged, crease {c:g}°", 4, "adjacent", c) for c in creases]


def run_scene(ctx, caps, path: Path, args) -> dict:
    """The reference, then each configuration of one scene."""
    scene = load_scene(path)
    ref, edges = reference(ctx, path, scene, args)
    warmup_s = args.warmup_s if caps.gpu_timers else 0.0  # no clock to ramp up on a software rasterizer
    rows, images = [], {}
    for label, samples, merge, crease in configs(args.crease):
        pipeline = with_settings(linear_pipeline(samples, merge=merge), {"merge_crease_deg": crease}, "aa_merge")
        r = Renderer(pipeline, ctx=ctx, method="presort_lf_et", method_overrides={"raster": "compute"})
        timing, frame = measure(r, scene, args.size, args, warmup_s)
        row = {
            "label": label,
            "samples": r.samples,
            "merge": merge,
            "merge_crease_deg": crease if merge != "off" else None,
            **timing,
            "stored": frame.stats["fragments"].get("stored"),
            **errors(frame.linear, ref, edges),
            "warnings": frame.stats.get("warnings", []),
        }
        r.release()
        rows.append(row)
        images[label] = frame.linear
        progress(
            f"  {label:32s} {row['ms']:9.3f} ms  stored {row['stored']:>9}  RMSE {row['rmse_255']:.2f}  "
            f"edge {row['edge_rmse_255']:.2f}"
        )
    crops(args.out / f"{path.stem}_crops.png", ref.image, ref.k, edges, images, rows)
    return {"scene": path.stem, "size": args.size, "ref_k": args.ref_k, "edge_pixels": int(edges.sum()), "rows": rows}


def crops(path: Path, ref_image, k: int, edges, images: dict, rows: list[dict], side: int = 96, zoom: int = 4) -> None:
    """A picture to look at: the window of `side` px with the most edge pixels, in the reference, at 1 sample,
    at 4 samples and merged (the first crease limit), each enlarged `zoom` times and labelled with its error."""
    from PIL import Image, ImageDraw

    from guaca_py.accuracy import srgb

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
    sheet.save(path)


def markdown(records: list[dict], command: str, device: str, timer: str) -> str:
    """One table per scene, each row against the 1-sample and the unmerged 4-sample row."""
    out = ["# antialiasing.merge: adjacent against unmerged samples", "", f"Command: `{command}`", ""]
    out += [f"Device: {device}; time: {timer} (wall time on a software rasterizer is no performance figure).", ""]
    for rec in records:
        one, four = rec["rows"][0], rec["rows"][1]
        out += [f"## {rec['scene']} ({rec['size']}², reference {rec['ref_k']}x, {rec['edge_pixels']} edge pixels)", ""]
        out += [
            "| configuration | ms | against 1 sample | SM MHz | stored | against 1 sample | RMSE | edge RMSE | FLIP |"
        ]
        out += ["|---|---|---|---|---|---|---|---|---|"]
        for r in rec["rows"]:
            fl = f"{r['flip']:.4f}" if isinstance(r["flip"], float) else "—"
            mhz = (r.get("clock") or {}).get("sm_clock_mhz_median", "—")
            out.append(
                f"| {r['label']} | {r['ms']:.3f} | {r['ms'] / one['ms']:.2f}x | {mhz} | {r['stored']} | "
                f"{r['stored'] / max(1, one['stored']):.2f}x | {r['rmse_255']:.2f} | {r['edge_rmse_255']:.2f} | {fl} |"
            )
        out.append("")
        for merged in rec["rows"][2:]:
            out.append(
                f"- {merged['label']}: {merged['stored'] / max(1, four['stored']):.0%} of the unmerged 4-sample "
                f"fragments; edge RMSE {one['edge_rmse_255'] / merged['edge_rmse_255']:.2f}x lower than 1 sample "
                f"(unmerged: {one['edge_rmse_255'] / four['edge_rmse_255']:.2f}x)."
            )
        out.append("")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_common_args(ap)
    ap.add_argument("--crease", nargs="*", type=float, default=[15.0], help="merge_crease_deg of the merged rows")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    ctx, caps = create_context(None)
    records = [run_scene(ctx, caps, path, args) for path in scene_paths(args)]
    command = "python benchmarks/aa_merge.py " + shlex.join(argv if argv is not None else sys.argv[1:])
    timer = "GPU timer queries" if caps.gpu_timers else "wall time"
    (args.out / "aa_merge.json").write_text(
        json.dumps(
            {"command": command, "device": caps.gl_renderer, "timer": timer, "scenes": records}, indent=1, default=str
        )
    )
    (args.out / "aa_merge.md").write_text(markdown(records, command, caps.gl_renderer, timer))
    progress(f"wrote {args.out}/aa_merge.md, .json")
    ctx.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
