"""Where a frame loop's wall time goes beyond the GPU's: idle gaps between frames and inside them.

Usage: python benchmarks/frame_gaps.py OUTDIR [--scenes DIR] [--only SCENE ...] [--methods ID ...]
                                       [--size 1024] [--frames 24] [--warmup-s 1.5]

Renders each (scene, method) in an application's loop (read_back=False, stats=False) with a GPU
timestamp (glQueryCounter) before the frame and after each pass, and the CPU time of each pass's
execute() call. A timestamp is taken when the GPU reaches it in the command stream, so from one
frame's last mark to the next frame's first is time the GPU had nothing to do; a pass whose GPU
span is longer than its timer-query time in the table waited for commands inside the frame. A
pass whose execute() takes the CPU much longer than it takes to issue its commands waited for
the GPU there. Writes OUTDIR/frame_gaps.json and frame_gaps.md.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from paper_table import PAPER, make_renderer, progress  # noqa: E402

from guaca_py.context import create_context  # noqa: E402
from guaca_py.gpu_timer import Timestamps  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def profile_loop(renderer, scene, size: int, frames: int) -> dict:
    """Per-frame GPU gap before the frame, GPU span per pass and CPU ms per pass, over `frames` loop frames."""
    marks = Timestamps()
    cpu: dict[str, list[float]] = {}
    originals = {}
    for p in renderer.passes:
        originals[p.name] = p.execute

        def timed(frame, p=p, run=p.execute):
            t0 = time.perf_counter()
            run(frame)
            marks.mark(f"{p.name}#{frame_no[0]}")
            cpu.setdefault(p.name, []).append((time.perf_counter() - t0) * 1e3)

        p.execute = timed
    frame_no = [0]
    renderer.ctx.finish()
    t0 = time.perf_counter()
    try:
        for i in range(frames):
            frame_no[0] = i
            marks.mark(f"gap#{i}")
            renderer.render(scene, size, size, read_back=False, stats=False)
        renderer.ctx.finish()
        wall = (time.perf_counter() - t0) * 1e3 / frames
        spans = marks.spans_ms()  # the span ending at each mark, by its label
    finally:
        for p in renderer.passes:
            p.execute = originals[p.name]
        marks.release()
    gaps = [spans[f"gap#{i}"] for i in range(1, frames) if f"gap#{i}" in spans]
    per_pass = {}
    for name in originals:
        gpu = [spans[f"{name}#{i}"] for i in range(frames) if f"{name}#{i}" in spans]
        if gpu:
            per_pass[name] = {"gpu_ms": statistics.median(gpu), "cpu_ms": statistics.median(cpu[name])}
    frame_spans = [
        sum(v for k, v in spans.items() if k.endswith(f"#{i}") and not k.startswith("gap")) for i in range(1, frames)
    ]
    return {
        "wall_ms": wall,
        "gap_ms_median": statistics.median(gaps),
        "gap_ms_max": max(gaps),
        "frame_span_ms_median": statistics.median(frame_spans),
        "passes": per_pass,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--scenes", default=".scenes")
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--methods", nargs="+", default=["presort_lf_et", "presort_lf", "unsorted_blend"])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--warmup-s", type=float, default=1.5)
    args = ap.parse_args()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx, _caps = create_context()
    rows = []
    for stem in PAPER:
        path = Path(args.scenes) / f"{stem}.yaml"
        if (args.only and stem not in args.only) or not path.is_file():
            continue
        scene = load_scene(path)
        for mid in args.methods:
            r = make_renderer(ctx, mid, "auto")
            t_end = time.perf_counter() + args.warmup_s
            while time.perf_counter() < t_end:  # the clock ramps up; the pool settles
                r.render(scene, args.size, args.size, read_back=False, stats=False)
            r.ctx.finish()
            row = {"scene": stem, "method": mid, **profile_loop(r, scene, args.size, args.frames)}
            r.release()
            rows.append(row)
            progress(
                f"{stem:<20} {mid:<16} wall {row['wall_ms']:8.3f}  GPU frame {row['frame_span_ms_median']:8.3f}  "
                f"gap {row['gap_ms_median']:.3f} (max {row['gap_ms_max']:.3f}) ms"
            )
    command = "python3 benchmarks/frame_gaps.py " + " ".join(sys.argv[1:])
    (out_dir / "frame_gaps.json").write_text(json.dumps({"command": command, "rows": rows}, indent=1))
    lines = [
        "# Frame loop: GPU gaps between frames and where each pass's time goes",
        "",
        f"Command: `{command}`",
        "",
        "GPU frame: from the frame's first timestamp to its last (median); gap: GPU idle between a "
        "frame's last mark and the next frame's first (median, max). Per pass: GPU span / CPU ms in execute().",
        "",
        "| scene | method | loop wall | GPU frame | gap (max) | passes: GPU span / CPU |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        passes = ", ".join(f"{k} {v['gpu_ms']:.3f}/{v['cpu_ms']:.3f}" for k, v in r["passes"].items())
        lines.append(
            f"| {r['scene']} | {r['method']} | {r['wall_ms']:.3f} | {r['frame_span_ms_median']:.3f} | "
            f"{r['gap_ms_median']:.3f} ({r['gap_ms_max']:.3f}) | {passes} |"
        )
    (out_dir / "frame_gaps.md").write_text("\n".join(lines) + "\n")
    progress(f"wrote {out_dir / 'frame_gaps.md'}")


if __name__ == "__main__":
    main()
