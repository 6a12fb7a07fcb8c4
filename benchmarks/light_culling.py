"""Composite-pass time against light count, with tiled light culling on (auto) and off.

Usage: python benchmarks/light_culling.py [--out DIR] [--size 1024] [--lights 1 2 4 ... 4096] [--frames 10]
                                          [--warmup 3] [--tile 16] [--tile-bits auto|cache|fetch]
                                          [--per-process] [--replot]
Scene: guaca_py.benchmarking.scenes.many_lights_doc (opaque solids, transparent panes and spheres,
point lights of range 1-2 scattered over a 20 x 20 area); light count n uses its first n lights.
Each count is rendered through the same pipeline (geometry, light_culling, composite, tone_mapping)
with culling 'auto' and 'off'; times are medians of --frames frames after --warmup untimed ones,
the point measured again while the SM clock was under 90% of its maximum. With --per-process every
light count is measured in a fresh process (over a long light-load run the driver lowers the clock).
Writes benchmarks/results/<device>/light_culling/light_culling.{json,md,png}.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from guaca_py import Renderer, pipeline_from_text
from guaca_py.benchmarking import Progress, Results, at_full_clock, bench_args, header, measure, open_device, time_label
from guaca_py.benchmarking.scenes import many_lights_doc
from guaca_py.scene.loader import load_scene_text

DEFAULT_LIGHTS = [2**k for k in range(13)]  # 1 .. 4096

PIPELINE = """\
name: light_culling_benchmark
transparency: {{method: presort_lf_et, threshold: 0.98, budget_mb: auto}}
passes:
  - geometry: {{}}
  - light_culling: {{mode: {mode}, tile_size: {tile}, max_lights: {max_lights}, tile_bits: {tile_bits}}}
  - composite: {{}}
  - tone_mapping: {{operator: aces}}
"""


def run_per_process(args) -> dict:
    """run() with each light count in its own process, merged into one record."""
    rows, record = [], {}
    t_start = time.perf_counter()
    progress = Progress(len(args.lights))
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.lights:
            cmd = [sys.executable, __file__, "--out", f"{tmp}/{n}", "--lights", str(n), "--size", str(args.size)]
            cmd += ["--frames", str(args.frames), "--warmup", str(args.warmup), "--tile", str(args.tile)]
            cmd += ["--tile-bits", args.tile_bits]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            record = json.loads(Path(tmp, str(n), "light_culling.json").read_text())
            rows += record["results"]
            progress.step(row_line(rows[-1]))
    record.update(results=rows, per_process=True, elapsed_s=round(time.perf_counter() - t_start, 1))
    return record


def run(args) -> dict:
    """Measure every (count, mode) in this process; the record."""
    device = open_device()
    counts = args.lights
    doc = many_lights_doc(max(counts), seed=0)
    scene = load_scene_text(yaml.safe_dump(doc), "many_lights")
    all_lights = list(scene.lights)
    renderers = {
        mode: Renderer(
            pipeline_from_text(
                PIPELINE.format(mode=mode, tile=args.tile, max_lights=max(counts), tile_bits=args.tile_bits)
            ),
            ctx=device.ctx,
        )
        for mode in ("auto", "off")
    }
    rows, resolved = [], None
    t_start = time.perf_counter()
    progress = Progress(len(counts))
    for n in counts:
        scene.lights = all_lights[:n]
        row = {"lights": n}
        for mode, r in renderers.items():
            m, clock, retries = at_full_clock(
                lambda r=r: measure(r, scene, args.size, args.size, args.warmup, args.frames)
            )
            s = m.last.stats
            if mode == "auto":
                resolved = s["lights"]["mode"]  # what `auto` resolved to on this device
            entry = {
                "composite_ms": round(m.pass_ms["composite"], 4),
                "light_culling_ms": round(m.pass_ms["light_culling"], 4),
                # the same work at every count: a yardstick of the clock the point ran at
                "tone_mapping_ms": round(m.pass_ms["tone_mapping"], 4),
                "visible": s["lights"]["visible"],
                "timer": m.timer,
            }
            if clock.summary():
                entry["sm_clock_mhz"] = clock.summary()["sm_clock_mhz_median"]
                entry["clock_retries"] = retries
            row["on" if mode == "auto" else "off"] = entry
        row["ratio_off_on"] = round(row["off"]["composite_ms"] / max(row["on"]["composite_ms"], 1e-9), 3)
        rows.append(row)
        progress.step(row_line(row))
    for r in renderers.values():
        r.release()
    record = {
        "device": device.name,
        "timer": rows[0]["on"]["timer"] if rows else None,
        "size": args.size,
        "tile_size": args.tile,
        "tile_bits": args.tile_bits,
        "frames": args.frames,
        "warmup": args.warmup,
        "statistic": "median",
        "culling_mode": resolved,
        "scene": "guaca_py.benchmarking.scenes.many_lights_doc (seed 0)",
        "transparency": "presort_lf_et",
        "results": rows,
        "elapsed_s": round(time.perf_counter() - t_start, 1),
    }
    device.release()
    return record


def row_line(row: dict) -> str:
    """One progress line per light count."""
    return (
        f"{row['lights']:>6} lights  on {row['on']['composite_ms']:9.3f} ms  off {row['off']['composite_ms']:9.3f} ms  "
        f"off/on {row['ratio_off_on']:7.2f}"
    )


def markdown(rec: dict) -> str:
    """The table: composite ms per light count, on and off, their ratio, the clock per point."""
    out = header(f"Light culling at {rec['size']}²", rec["device"], rec["command"], rec.get("timer"))
    at_1024 = next((r["ratio_off_on"] for r in rec["results"] if r["lights"] == 1024), None)
    alone = ", each light count in its own process" if rec.get("per_process") else ""
    out += [
        f"Culling `auto` resolved to `{rec['culling_mode']}`; tile {rec['tile_size']} px; median of {rec['frames']} "
        f"frames after {rec['warmup']} warm-up{alone}."
        + (f" Off against on at 1024 lights: **{at_1024}x**." if at_1024 else ""),
        "",
        "| lights | composite ms, on | off | off / on | light culling ms | tone mapping ms on / off | SM MHz on / off |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rec["results"]:
        on, off = r["on"], r["off"]
        out.append(
            f"| {r['lights']} | {on['composite_ms']:.3f} | {off['composite_ms']:.3f} | {r['ratio_off_on']:.2f} | "
            f"{on['light_culling_ms']:.3f} | {on['tone_mapping_ms']:.3f} / {off['tone_mapping_ms']:.3f} | "
            f"{on.get('sm_clock_mhz', '—')} / {off.get('sm_clock_mhz', '—')} |"
        )
    return "\n".join(out) + "\n"


def chart(rec: dict):
    """A drawing function: composite time against light count, culling on and off (log-log)."""

    def draw(plt):
        rows = rec["results"]
        n = [r["lights"] for r in rows]
        fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
        ax.plot(n, [r["on"]["composite_ms"] for r in rows], "o-", label=f"culling on ({rec['culling_mode']})")
        ax.plot(n, [r["off"]["composite_ms"] for r in rows], "s--", label="culling off (every light everywhere)")
        clocks = [e["sm_clock_mhz"] for r in rows for e in (r["on"], r["off"]) if "sm_clock_mhz" in e]
        for r in rows:  # points the GPU ran at a throttled clock (even after retries) say so
            for key in ("on", "off"):
                mhz = r[key].get("sm_clock_mhz")
                if mhz and mhz < 0.9 * max(clocks):
                    ax.annotate(
                        f"{mhz:.0f} MHz",
                        (r["lights"], r[key]["composite_ms"]),
                        fontsize=7,
                        color="tab:red",
                        xytext=(-40, 6),
                        textcoords="offset points",
                    )
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("lights in the scene")
        ax.set_ylabel(time_label(rec.get("timer"), f"ms, composite pass (median of {rec['frames']})"))
        ax.set_title(f"Shade-composite time vs light count, {rec['size']}x{rec['size']}\n{rec['device']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        return fig

    return draw


def main(argv: list[str] | None = None) -> int:
    """Measure (or rebuild the table and chart with --replot)."""
    ap = bench_args(__file__, __doc__, size=1024, frames=10)
    ap.set_defaults(warmup=3)
    ap.add_argument("--lights", type=int, nargs="+", default=DEFAULT_LIGHTS)
    ap.add_argument("--tile", type=int, default=16)
    ap.add_argument("--tile-bits", default="auto", choices=("auto", "cache", "fetch"))
    ap.add_argument("--per-process", action="store_true", help="measure each light count in a fresh process")
    args = ap.parse_args(argv)
    args.lights = sorted(set(args.lights))
    if args.replot:
        res = Results.existing(args, argv)
        rec = res.read_json()
    else:
        rec = run_per_process(args) if args.per_process else run(args)
        res = Results(args, rec["device"], argv)
    res.finish(rec, markdown, chart)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
