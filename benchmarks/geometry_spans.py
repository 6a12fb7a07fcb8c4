"""GPU time of each part of the geometry pass: the G-buffer's depth clear, the method's prepare and the compute rasterizer's stages.

Usage: python benchmarks/geometry_spans.py SCENE [SCENE ...] [--scenes .scenes] [--size 1024] [--samples 1 4]
                                          [--raster auto]

The compute rasterizer's stage profiling (GUACA_RASTER_STAGES=1) marks GPU timestamps between its
stages; this script adds two marks before them, at the start of the geometry pass and around the
transparency method's prepare(), so `depth_clear` is the span of the G-buffer clear (and any opaque
draws) and `prepare` that of the method's list clears. Medians of 30 frames after a 1.5 s warm-up,
printed one line per scene and sample count.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ["GUACA_RASTER_STAGES"] = "1"
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]

from guaca_py import Renderer  # noqa: E402
from guaca_py.antialiasing import with_samples  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.methods.presort_lf import PreSortLF  # noqa: E402
from guaca_py.passes.geometry import GeometryPass  # noqa: E402
from guaca_py.pipeline.config import load_pipeline  # noqa: E402
from guaca_py.scene.loader import load_scene  # noqa: E402


def _marked() -> None:
    """Wrap the geometry pass and presort_lf's prepare() with the rasterizer's stage marks."""
    execute, prepare = GeometryPass.execute, PreSortLF.prepare

    def marked_execute(self, frame):
        self.renderer.raster.compute._mark("pre")
        return execute(self, frame)

    def marked_prepare(self, frame):
        frame.renderer.raster.compute._mark("depth_clear")
        prepare(self, frame)
        frame.renderer.raster.compute._mark("prepare")

    GeometryPass.execute, PreSortLF.prepare = marked_execute, marked_prepare


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene_names", nargs="+")
    ap.add_argument("--scenes", type=Path, default=ROOT / ".scenes")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--samples", nargs="+", type=int, default=[1, 4])
    ap.add_argument("--raster", default="auto", help="transparency.raster (compute: also on a software rasterizer)")
    args = ap.parse_args()
    _marked()
    ctx, _ = create_context()
    for name in args.scene_names:
        scene = load_scene(args.scenes / f"{name}.yaml")
        for n in args.samples:
            r = Renderer(
                with_samples(load_pipeline("default"), n),
                ctx=ctx,
                method_overrides={"raster": args.raster},
                restore_host_state=False,
            )
            t_end = time.perf_counter() + 1.5
            while time.perf_counter() < t_end:  # the SM clock ramps up
                r.render(scene, args.size, args.size, read_back=False, stats=False)
            rows = []
            for _ in range(30):
                res = r.render(scene, args.size, args.size)
                spans = dict(res.stats["raster"]["compute"]["stage_ms"])
                spans["geometry_pass"] = res.stats["passes"]["geometry"]["ms"]
                spans["composite_pass"] = res.stats["passes"]["composite"]["ms"]
                rows.append(spans)
            med = {k: round(statistics.median(row.get(k, 0.0) for row in rows), 3) for k in rows[-1]}
            print(name, n, med, flush=True)
            r.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
