"""Where a frame loop's CPU time goes: cProfile of renders without read-back, beside GPU time.

Usage: python benchmarks/loop_profile.py OUTDIR --scenes DIR [--scene-names NAME ...] [--method ID]
                                         [--size 1024] [--frames 24] [--loops 3]

For each scene: paper_table.py's timing (warm-up, per-pass GPU medians at the maximum SM clock, and
the wall time per frame of a loop of renders without read-back and without timers, as an
application runs it), then that loop again under cProfile. A loop whose wall time exceeds its
frames' GPU time is paced by the CPU (Python and driver work, or a wait for the GPU inside the
frame); the profile says which calls it is in. Writes OUTDIR/loop_profile.md.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from paper_table import loop_wall_ms, progress, time_frames  # noqa: E402

from guaca_py import Renderer  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def submit_alone_ms(renderer, scene, size: int, frames: int) -> list[float]:
    """Wall time of render() calls each started on an idle GPU: what the CPU spends submitting a frame.

    In a loop the driver's calling thread spins while the GPU is behind, so neither the loop's wall
    time nor its CPU time tells a CPU-paced loop from a GPU-paced one; a frame submitted alone does.
    """
    times = []
    for _ in range(frames):
        renderer.ctx.finish()
        t0 = time.perf_counter()
        renderer.render(scene, size, size, read_back=False, stats=False)
        times.append((time.perf_counter() - t0) * 1e3)
    renderer.ctx.finish()
    return times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scenes", type=Path, required=True)
    ap.add_argument("--scene-names", nargs="+", default=["dragons", "hairball_v1"])
    ap.add_argument("--method", default="presort_lf_et")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--loops", type=int, default=3, help="loops timed again after the profiled one")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    ctx, _ = create_context()
    lines = [f"# Frame loop profile ({args.method}, {args.size}², {args.frames} frames)", ""]
    for name in args.scene_names:
        scene = load_scene(args.scenes / f"{name}.yaml")
        r = Renderer("default", ctx=ctx, method=args.method, restore_host_state=False)
        row = time_frames(r, scene, args.size, 1.5, 8)
        gpu, wall = row["total_ms"], row["loop_wall_ms"]
        clock = (row.get("clock") or {}).get("sm_clock_mhz_median", "—")
        prof = cProfile.Profile()
        prof.enable()
        profiled = loop_wall_ms(r, scene, args.size, args.frames, stats=False)["wall"]
        prof.disable()
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(25)
        pstats.Stats(prof, stream=text).sort_stats("cumulative").print_stats(40)
        loops = [loop_wall_ms(r, scene, args.size, args.frames, stats=False) for _ in range(args.loops)]
        alone = submit_alone_ms(r, scene, args.size, args.frames)
        lines += [
            f"## {name}",
            "",
            f"GPU total (median of 8 timed frames, SM clock {clock} MHz): {gpu:.3f} ms; loop wall: "
            f"{wall:.3f} ms per frame (+{wall - gpu:.3f}); under cProfile: {profiled:.3f} ms",
            "",
            f"CPU cost of a frame alone (render() called on an idle GPU, no wait inside; median of {args.frames}): "
            f"**{statistics.median(alone):.3f} ms** (min {min(alone):.3f}, max {max(alone):.3f})",
            "",
            "Loops again, ms per frame (wall; inside render(); CPU time of the process, and of the calling thread; GPU time of the loop's "
            "frames from timestamps at their ends; GPU idle between frames):",
            "",
            "| wall | submit | cpu | thread cpu | gpu | idle |",
            "|---|---|---|---|---|---|",
            *(
                f"| {x['wall']:.3f} | {x['submit']:.3f} | {x['cpu']:.3f} | {x['thread_cpu']:.3f} | {x.get('gpu', 0):.3f} | {x.get('idle', 0):.3f} |"
                for x in loops
            ),
            "",
            "```",
            text.getvalue().strip(),
            "```",
            "",
        ]
        progress(f"{name}: GPU {gpu:.3f} ms at {clock} MHz, loop wall {wall:.3f} ms, profiled {profiled:.3f} ms")
        r.release()
    (args.out / "loop_profile.md").write_text("\n".join(lines))
    progress(f"wrote {args.out / 'loop_profile.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
