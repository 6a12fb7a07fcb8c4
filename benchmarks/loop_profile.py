"""Where a frame loop's CPU time goes: cProfile of renders without read-back, beside GPU time.

Usage: python benchmarks/loop_profile.py OUTDIR --scenes DIR [--scene-names NAME ...] [--method ID]
                                         [--size 1024] [--frames 24]

For each scene: a warm-up, the median GPU time of frames rendered one at a time (per-pass timers),
then the wall time per frame of a loop of --frames renders without read-back and without timers
(stats=False), as an application runs it, and that loop again under cProfile. A loop whose wall
time exceeds its frames' GPU time is paced by the CPU (Python and driver work, or a wait for the
GPU inside the frame); the profile says which calls it is in. Writes OUTDIR/loop_profile.md.
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

from guaca_py import Renderer  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def loop_ms(renderer: Renderer, scene, size: int, frames: int) -> float:
    """Wall time per frame of `frames` renders without read-back, from an idle GPU to the last one's end."""
    renderer.ctx.finish()
    t0 = time.perf_counter()
    for _ in range(frames):
        renderer.render(scene, size, size, read_back=False, stats=False)
    renderer.ctx.finish()
    return (time.perf_counter() - t0) * 1e3 / frames


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--scenes", type=Path, required=True)
    ap.add_argument("--scene-names", nargs="+", default=["dragons", "hairball_v1"])
    ap.add_argument("--method", default="presort_lf_et")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=24)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    ctx, _ = create_context()
    lines = [f"# Frame loop profile ({args.method}, {args.size}², {args.frames} frames)", ""]
    for name in args.scene_names:
        scene = load_scene(args.scenes / f"{name}.yaml")
        r = Renderer("default", ctx=ctx, method=args.method, restore_host_state=False)
        t_end = time.perf_counter() + 1.5
        while time.perf_counter() < t_end:  # warm-up: compile, size the pool, ramp the clock
            r.render(scene, args.size, args.size)
        gpu = statistics.median(
            sum(p["ms"] for p in r.render(scene, args.size, args.size).stats["passes"].values()) for _ in range(8)
        )
        wall = loop_ms(r, scene, args.size, args.frames)
        prof = cProfile.Profile()
        prof.enable()
        profiled = loop_ms(r, scene, args.size, args.frames)
        prof.disable()
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(25)
        lines += [
            f"## {name}",
            "",
            f"GPU total (frames one at a time, median of 8): {gpu:.3f} ms; loop wall: {wall:.3f} ms per frame "
            f"(+{wall - gpu:.3f}); under cProfile: {profiled:.3f} ms",
            "",
            "```",
            text.getvalue().strip(),
            "```",
            "",
        ]
        print(f"{name}: GPU {gpu:.3f} ms, loop wall {wall:.3f} ms, profiled {profiled:.3f} ms", flush=True)
        r.release()
    (args.out / "loop_profile.md").write_text("\n".join(lines))
    print(f"wrote {args.out / 'loop_profile.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
