"""CPU cost of submitting a frame, this tree against a base tree, interleaved frame by frame in one process.

Usage: python benchmarks/ab_submit.py OUTDIR --base DIR [--scenes .scenes] [--scene-names NAME ...]
                                      [--size 1024] [--frames 60] [--method presort_lf_et]

DIR holds a copy of the base commit's package renamed `guaca_base` (its imports are relative) beside
its shader_templates/, materials/ and pipelines/, e.g.
    mkdir -p ab_base && git archive REV guaca_py shader_templates materials pipelines | tar -x -C ab_base
    mv ab_base/guaca_py ab_base/guaca_base
Each frame is submitted on an idle GPU (render() without read-back after a finish), alternating
between the two renderers, so both see the same CPU load over time: on a shared host the
submission time of one process drifts by tens of percent between runs. GPU time is the renderers'
own per-pass timers (median of timed frames after a warm-up). Writes OUTDIR/ab_submit.md.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from paper_table import progress  # noqa: E402

import guaca_py  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--base", type=Path, required=True)
    ap.add_argument("--scenes", type=Path, default=ROOT / ".scenes")
    ap.add_argument("--scene-names", nargs="+", default=["dragons", "sponza_dabrovic_v1", "sponza_dabrovic_v2"])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--method", default="presort_lf_et")
    args = ap.parse_args()
    sys.path.insert(0, str(args.base.resolve()))
    import guaca_base  # the base tree's package  # noqa: PLC0415

    args.out.mkdir(parents=True, exist_ok=True)
    ctx, _ = create_context()
    lines = [
        f"# Submitting a frame: this tree against {args.base} ({args.method}, {args.size}², {args.frames} frames each)",
        "",
        "| scene | tree | submit median ms | min | p90 | GPU ms (timed frames) | faster |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in args.scene_names:
        scene = load_scene(args.scenes / f"{name}.yaml")
        sides = {
            "base": guaca_base.Renderer("default", ctx=ctx, method=args.method, restore_host_state=False),
            "new": guaca_py.Renderer("default", ctx=ctx, method=args.method, restore_host_state=False),
        }
        gpu = {}
        for side, r in sides.items():  # warm-up (the clock ramps up), then the frames' own GPU timers
            t_end = time.perf_counter() + 1.0
            while time.perf_counter() < t_end:
                r.render(scene, args.size, args.size, read_back=False)
            ctx.finish()
            gpu[side] = statistics.median(
                sum(p["ms"] for p in r.render(scene, args.size, args.size).stats["passes"].values()) for _ in range(8)
            )
        times = {side: [] for side in sides}
        for _ in range(args.frames):
            for side, r in sides.items():
                ctx.finish()
                t0 = time.perf_counter()
                r.render(scene, args.size, args.size, read_back=False, stats=False)
                times[side].append((time.perf_counter() - t0) * 1e3)
        ctx.finish()
        med = {s: statistics.median(t) for s, t in times.items()}
        for side, t in times.items():
            t = sorted(t)
            faster = f"{med['base'] / med['new']:.2f}×" if side == "new" else ""
            lines.append(
                f"| {name} | {side} | {med[side]:.3f} | {t[0]:.3f} | {t[int(0.9 * (len(t) - 1))]:.3f} | "
                f"{gpu[side]:.3f} | {faster} |"
            )
        progress(
            f"{name}: submit base {med['base']:.3f} ms, new {med['new']:.3f} ms; GPU {gpu['base']:.3f} / {gpu['new']:.3f}"
        )
        for r in sides.values():
            r.release()
    (args.out / "ab_submit.md").write_text("\n".join(lines) + "\n")
    progress(f"wrote {args.out / 'ab_submit.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
