"""Where a frame loop's CPU time goes: cProfile of renders without read-back, beside GPU time.

Usage: python benchmarks/loop_profile.py OUTDIR --scenes DIR [--scene-names NAME ...] [--method ID]
                                         [--size 1024] [--frames 24]

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
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from paper_table import loop_wall_ms, progress, time_frames  # noqa: E402

from guaca_py import Renderer  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


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
        row = time_frames(r, scene, args.size, 1.5, 8)
        gpu, wall = row["total_ms"], row["loop_wall_ms"]
        clock = (row.get("clock") or {}).get("sm_clock_mhz_median", "—")
        prof = cProfile.Profile()
        prof.enable()
        profiled = loop_wall_ms(r, scene, args.size, args.frames, stats=False)["wall"]
        prof.disable()
        text = io.StringIO()
        pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(25)
        lines += [
            f"## {name}",
            "",
            f"GPU total (median of 8 timed frames, SM clock {clock} MHz): {gpu:.3f} ms; loop wall: "
            f"{wall:.3f} ms per frame (+{wall - gpu:.3f}); under cProfile: {profiled:.3f} ms",
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
