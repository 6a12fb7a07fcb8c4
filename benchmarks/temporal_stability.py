"""Temporal stability along a camera path: flicker on pixels that should not change, and bit identity.

Usage: python benchmarks/temporal_stability.py [--out DIR] [--scenes .scenes] [--scene-names NAME ...]
                                               [--size 1024] [--frames 60] [--degrees 3] [--ref-k 2] [--tile 2048]
                                               [--tolerance 1] [--repeat 4] [--methods ID ...] [--samples 4]
                                               [--supersample K ...] [--scene-budget-s S] [--replot]
Path: --frames poses orbiting the scene camera's target about its up axis by --degrees in all
(small steps: edges crawl by a fraction of a pixel per frame). Pixels that should not change
between frames t and t+1: those whose supersampled exact reference (presort_lf at --ref-k x, in
tiles of at most --tile px, box filtered) changes by less than --tolerance/255 in every channel.
Per configuration (every method at 1 sample, skipped where the device refuses it; presort_lf_et at each --samples
and supersampled at each --supersample factor, none by default; the first method runs first, then the sample
counts and supersampling factors, then the others): the mean over frame pairs
of the mean |difference| (1/255, linear output clipped to [0, 1]) on those pixels, the share of
them that moved by more than --tolerance/255 (flicker), and whether rendering --repeat poses of
the path again gives bit-identical images (races in overflow, ties, stochastic seeds). Pipeline:
guaca_py.reference.linear_pipeline (threshold 0.999, culled lights, linear output). A supersample row
at the reference's factor renders what the reference renders (presort_lf, box filtered the same) and
would move only where the reference moves: each --supersample factor must be below --ref-k (default 2,
so compare supersample 2 with --ref-k 4). Once a scene
has run for --scene-budget-s (reference included), its remaining configurations are skipped
(the first always runs). No times: accuracy does not depend on the timer.
Writes benchmarks/results/<device>/temporal_stability/<scene>/stability.{json,md} and its README.md.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np

from guaca_py import Renderer
from guaca_py.antialiasing import with_supersample
from guaca_py.benchmarking import (
    Progress,
    Results,
    add_reference_args,
    bench_args,
    config_rows,
    open_device,
    scene_paths,
)
from guaca_py.benchmarking.aa_chart import AA_METHOD
from guaca_py.methods import method_class, method_ids
from guaca_py.reference import linear_pipeline, supersampled
from guaca_py.scene.loader import load_scene

REFERENCE_METHOD = "presort_lf"


def camera_path(scene, frames: int, degrees: float) -> list:
    """Scenes whose cameras orbit the target about the up axis, `degrees` in all over `frames` poses."""
    cam = scene.camera
    target = np.asarray(cam.target, np.float64)
    up = np.asarray(cam.up, np.float64)
    up /= np.linalg.norm(up)
    offset = np.asarray(cam.position, np.float64) - target
    out = []
    for i in range(frames):
        a = math.radians(degrees) * (i / max(1, frames - 1) - 0.5)
        # Rodrigues rotation of the eye offset about `up`
        rot = offset * math.cos(a) + np.cross(up, offset) * math.sin(a) + up * (up @ offset) * (1 - math.cos(a))
        moved = dataclasses.replace(cam, position=tuple(float(x) for x in target + rot))
        out.append(dataclasses.replace(scene, camera=moved))
    return out


def diff_255(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel largest channel difference in 1/255 of two linear images clipped to [0, 1]."""
    return np.abs(np.clip(a, 0, 1) - np.clip(b, 0, 1)).max(axis=-1) * 255.0


def stable_masks(ctx, poses: list, size: int, k: int, tolerance: float, tile: int) -> tuple[list[np.ndarray], int]:
    """Per consecutive pair of poses: pixels whose supersampled exact reference changes by < tolerance/255;
    and the fragments its A-buffer dropped over the path (0 unless a tile overflowed the pool)."""
    r = Renderer(linear_pipeline(1), ctx=ctx, method=REFERENCE_METHOD, method_overrides={"raster": "hardware"})
    masks, prev, overflow = [], None, 0
    for scene in poses:
        ref = supersampled(r, scene, size, size, k, tile)
        overflow += ref.overflow
        if prev is not None:
            masks.append(diff_255(ref.image, prev) < tolerance)
        prev = ref.image
    r.release()
    return masks, overflow


def configs(args) -> list[tuple[str, str, int, int]]:
    """(label, method, samples, supersample): every method at 1 sample, presort_lf_et's extra sample counts and
    supersampling factors right after the first method (a scene's time budget then cuts the method list, not
    the anti-aliasing rows)."""
    confs = [(m, m, 1, 1) for m in (args.methods or method_ids())]
    confs[1:1] = [(f"{AA_METHOD} x{n}", AA_METHOD, n, 1) for n in args.samples if n > 1] + [
        (f"{AA_METHOD} supersample {k}", AA_METHOD, 1, k) for k in args.supersample if k > 1
    ]
    return confs


def run_config(r: Renderer, poses: list, size: int, masks: list, tolerance: float, repeat: int) -> dict:
    """Flicker along the path and bit identity of repeated poses for one renderer."""
    keep = set(np.linspace(0, len(poses) - 1, max(1, repeat)).round().astype(int).tolist())
    kept, means, moved, prev, samples = {}, [], [], None, None
    for i, scene in enumerate(poses):
        frame = r.render(scene, size, size)
        img, samples = frame.linear, frame.stats.get("antialiasing", {}).get("samples")
        if i in keep:
            kept[i] = img.copy()
        if prev is not None:
            m = masks[i - 1]
            d = diff_255(img, prev)[m]
            if d.size:
                means.append(float(d.mean()))
                moved.append(float(np.mean(d > tolerance)))
        prev = img
    identical, worst = True, 0.0
    for i in sorted(kept):
        again = r.render(poses[i], size, size).linear
        if not np.array_equal(again, kept[i]):
            identical = False
            worst = max(worst, float(np.abs(again - kept[i]).max() * 255.0))
    return {
        "mean_diff_255": float(np.mean(means)) if means else float("nan"),
        "flicker_share": float(np.mean(moved)) if moved else float("nan"),
        "bit_identical": identical,
        "repeat_max_diff_255": worst,
        "repeated_poses": sorted(kept),
        **({"samples": samples} if samples else {}),  # as rendered (a device may round the count up)
    }


def run_scene(ctx, path: Path, args, progress: Progress) -> dict:
    """Reference masks, then every configuration (until --scene-budget-s), for one scene."""
    t0 = time.perf_counter()
    scene = load_scene(path)
    poses = camera_path(scene, args.frames, args.degrees)
    masks, overflow = stable_masks(ctx, poses, args.size, args.ref_k, args.tolerance, args.tile)
    share = float(np.mean([m.mean() for m in masks])) if masks else 0.0
    progress.note(
        f"{path.stem}: reference {time.perf_counter() - t0:.1f} s, stable pixels {share:.1%} per pair"
        + (
            f", OVERFLOW: {overflow} fragments dropped in tiles already split to the smallest (256 px): a --tile below 256 or a larger pool"
            if overflow
            else ""
        )
    )

    def measure_row(r: Renderer, row: dict) -> None:
        row.update(run_config(r, poses, args.size, masks, args.tolerance, args.repeat))

    def report(row: dict) -> None:
        if "skipped" in row:
            progress.step(f"{path.stem} {row['label']}: skipped ({row['skipped']})")
            return
        progress.step(
            f"{path.stem} {row['label']:28s} mean diff {row['mean_diff_255']:7.3f}/255  "
            f"flicker {row['flicker_share']:7.2%}  bit-identical {row['bit_identical']}  ({row['seconds']:.1f} s)"
        )

    def renderer(n: int, k: int, mid: str):
        return lambda: Renderer(with_supersample(linear_pipeline(n), k, "--supersample"), ctx=ctx, method=mid)

    def row(label: str, mid: str, n: int, k: int) -> dict:
        return {"label": label, "method": mid, "samples": n, "exact": method_class(mid).exact, "supersample": k}

    rows = config_rows(
        ((row(label, mid, n, k), renderer(n, k, mid)) for label, mid, n, k in configs(args)),
        measure_row,
        report,
        t0,
        args.scene_budget_s,
    )
    return {
        "scene": path.stem,
        "size": args.size,
        "frames": args.frames,
        "degrees": args.degrees,
        "reference": {
            "method": REFERENCE_METHOD,
            "k": args.ref_k,
            "tile_px": args.tile,
            "overflow": overflow,
            "tolerance_255": args.tolerance,
        },
        "stable_share": share,
        "rows": rows,
    }


def samples(row: dict) -> str:
    """A row's samples per pixel, and its supersampling factor where it has one."""
    k = row.get("supersample", 1)
    return f"{row['samples']}" + (f" (supersample {k}: {row['samples'] * k * k} per pixel)" if k > 1 else "")


def markdown(rec: dict) -> str:
    """One scene's table."""
    ref = rec["reference"]
    out = [
        f"# {rec['scene']}: temporal stability, {rec['frames']} frames at {rec['size']}²",
        "",
        f"Device: {rec['device']}. Path: orbit of {rec['degrees']}° about the target. Pixels that should not change: "
        f"reference (`{ref['method']}` {ref['k']}x{ref['k']}, box filtered) moves < {ref['tolerance_255']}/255 "
        f"between the two frames ({rec['stable_share']:.1%} of pixels per pair on average)"
        + (
            f"; NOT EXACT: its A-buffer dropped {ref['overflow']} fragments over the path."
            if ref.get("overflow")
            else "."
        ),
        "",
        f"Command: `{rec['command']}`",
        "",
        "| configuration | exact | samples | mean frame-to-frame diff (1/255) | flicker (> tolerance) | bit-identical repeat |",
        "|---|---|---|---|---|---|",
    ]
    for r in rec["rows"]:
        if "skipped" in r:
            out.append(f"| {r['label']} | | {samples(r)} | skipped: {r['skipped']} | | |")
            continue
        ident = "yes" if r["bit_identical"] else f"no (max {r['repeat_max_diff_255']:.2f}/255)"
        out.append(
            f"| {r['label']} | {'yes' if r['exact'] else 'no'} | {samples(r)} | {r['mean_diff_255']:.3f} | "
            f"{r['flicker_share']:.2%} | {ident} |"
        )
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Measure stability per scene (or rebuild the tables with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=60, scenes=True)
    add_reference_args(ap, k=2)
    ap.add_argument("--degrees", type=float, default=3.0, help="orbit angle over the whole path")
    ap.add_argument("--tolerance", type=float, default=1.0, help="in 1/255: reference change below = should not change")
    ap.add_argument("--repeat", type=int, default=4, help="poses rendered again for the bit-identity check")
    ap.add_argument("--methods", nargs="*", help="methods at 1 sample (default: every method the device runs)")
    ap.add_argument("--samples", nargs="*", type=int, default=[4], help=f"extra sample counts of {AA_METHOD}")
    ap.add_argument(
        "--supersample", nargs="*", type=int, default=[], help=f"supersampling factors of {AA_METHOD}, below --ref-k"
    )
    ap.add_argument(
        "--scene-budget-s", type=float, default=0.0, help="per scene (reference included): later configurations skipped"
    )
    args = ap.parse_args(argv)
    finest = max(args.supersample, default=1)
    if finest > 1 and finest >= args.ref_k:  # the reference would be that row itself, or coarser
        ap.error(f"--supersample {finest} needs --ref-k above {finest} (the reference is {args.ref_k}x{args.ref_k})")
    if args.replot:
        res = Results.existing(args, argv)
    else:
        device = open_device()
        res = Results(args, device.name, argv)
        paths = scene_paths(args)
        progress = Progress(len(paths) * len(configs(args)))
        for path in paths:
            rec = run_scene(device.ctx, path, args, progress)
            rec.update(device=device.name, command=res.command)
            (res.dir / rec["scene"]).mkdir(parents=True, exist_ok=True)
            (res.dir / rec["scene"] / "stability.json").write_text(json.dumps(rec, indent=1))
    # the index lists every scene in the folder, also those of earlier runs
    recs = [json.loads(p.read_text()) for p in sorted(res.dir.glob("*/stability.json"))]
    index = ["# Temporal stability", ""]
    for rec in recs:
        (res.dir / rec["scene"] / "stability.md").write_text(markdown(rec))
        index.append(
            f"- [{rec['scene']}]({rec['scene']}/stability.md) ({rec['frames']} frames at {rec['size']}², "
            f"{rec['device']}): `{rec['command']}`"
        )
    (res.dir / "README.md").write_text("\n".join(index) + "\n")
    print(f"wrote {res.dir}/README.md and {len(recs)} scene folders", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
