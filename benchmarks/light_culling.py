"""Composite-pass time against light count, with tiled light culling on (auto) and off.

Usage: python benchmarks/light_culling.py OUTDIR [--size 1024] [--lights 1 2 4 ... 4096]
                                          [--frames 10] [--warmup 3] [--tile 16]
Scene: benchmarks/scenes/many_lights.py (opaque solids, transparent panes and spheres, point
lights of range 1-2 scattered over a 20 x 20 area); light count n uses its first n lights.
Each count is rendered through the same pipeline (geometry, light_culling, composite,
tone_mapping) with culling 'auto' and 'off'; times are medians of --frames frames after
--warmup untimed ones, GPU timer queries where the device has them (wall time otherwise).
Writes OUTDIR/light_culling.json and OUTDIR/light_culling.png; prints a table and the
off/on composite-time ratio at 1024 lights. With --per-process every light count is measured
in a fresh process (the GPU driver lowers the clock over a long light-load run: see
benchmarks/gpu_clock.py); the SM clock is recorded per point where nvidia-smi exists.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks" / "scenes"), str(ROOT / "benchmarks")]

from gpu_clock import at_full_clock  # noqa: E402
from many_lights import many_lights_doc  # noqa: E402

from guaca_py import Renderer, pipeline_from_text  # noqa: E402
from guaca_py.benchmarking import measure  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.scene.loader import load_scene_text  # noqa: E402

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


def run_per_process(
    out: Path, size: int, counts: list[int], frames: int, warmup: int, tile: int, tile_bits: str = "auto"
) -> dict:
    """run() with each light count in its own process; merged into one result in `out`."""
    rows, result = [], None
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for n in counts:
            sub = Path(tmp) / str(n)
            cmd = [
                sys.executable,
                __file__,
                str(sub),
                "--size",
                str(size),
                "--lights",
                str(n),
                "--frames",
                str(frames),
                "--warmup",
                str(warmup),
                "--tile",
                str(tile),
                "--tile-bits",
                tile_bits,
            ]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            result = json.loads((sub / "light_culling.json").read_text())
            rows += result["results"]
            print(_row_line(rows[-1]), flush=True)
    result.update(
        results=rows,
        per_process=True,
        elapsed_s=round(time.perf_counter() - t_start, 1),
        ratio_off_on_at_1024=next((r["ratio_off_on"] for r in rows if r["lights"] == 1024), None),
    )
    out.mkdir(parents=True, exist_ok=True)
    (out / "light_culling.json").write_text(json.dumps(result, indent=2))
    _chart(result, out / "light_culling.png")
    return result


def run(out: Path, size: int, counts: list[int], frames: int, warmup: int, tile: int, tile_bits: str = "auto") -> dict:
    """Measure every (count, mode); write JSON and chart into `out`; return the results."""
    ctx, caps = create_context()
    doc = many_lights_doc(max(counts), seed=0)
    scene = load_scene_text(yaml.safe_dump(doc), "many_lights")
    all_lights = list(scene.lights)
    renderers = {
        mode: Renderer(
            pipeline_from_text(PIPELINE.format(mode=mode, tile=tile, max_lights=max(counts), tile_bits=tile_bits)),
            ctx=ctx,
        )
        for mode in ("auto", "off")
    }
    resolved = renderers["auto"].pass_named("light_culling").mode
    rows = []
    t_start = time.perf_counter()
    for n in counts:
        scene.lights = all_lights[:n]
        row = {"lights": n}
        for mode, r in renderers.items():
            m, clock, retries = at_full_clock(lambda r=r: measure(r, scene, size, size, warmup, frames))
            s = m.last.stats
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
            if mode == "auto":
                counts_per_tile = r.pass_named("light_culling").grid_bits().sum(axis=0)
                entry["tile_lights_mean"] = round(float(counts_per_tile.mean()), 3)
                entry["tile_lights_max"] = int(counts_per_tile.max())
            row["on" if mode == "auto" else "off"] = entry
        row["ratio_off_on"] = round(row["off"]["composite_ms"] / max(row["on"]["composite_ms"], 1e-9), 3)
        rows.append(row)
        print(_row_line(row), flush=True)
    for r in renderers.values():
        r.release()
    at_1024 = next((r["ratio_off_on"] for r in rows if r["lights"] == 1024), None)
    result = {
        "device": caps.gl_renderer,
        "timer": rows[0]["on"]["timer"] if rows else None,
        "size": size,
        "tile_size": tile,
        "frames": frames,
        "warmup": warmup,
        "statistic": "median",
        "culling_mode": resolved,
        "scene": "benchmarks/scenes/many_lights.py (seed 0)",
        "transparency": "presort_lf_et",
        "results": rows,
        "ratio_off_on_at_1024": at_1024,
        "elapsed_s": round(time.perf_counter() - t_start, 1),
    }
    out.mkdir(parents=True, exist_ok=True)
    (out / "light_culling.json").write_text(json.dumps(result, indent=2))
    _chart(result, out / "light_culling.png")
    return result


def _row_line(row: dict) -> str:
    """One progress line per light count."""
    return (
        f"{row['lights']:>6} lights  on {row['on']['composite_ms']:9.3f} ms  off {row['off']['composite_ms']:9.3f} ms  "
        f"off/on {row['ratio_off_on']:7.2f}  tile mean {row['on']['tile_lights_mean']:8.2f}"
    )


def _chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["results"]
    n = [r["lights"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=110)
    ax.plot(n, [r["on"]["composite_ms"] for r in rows], "o-", label=f"culling on ({result['culling_mode']})")
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
    ax.set_ylabel(f"composite pass, ms ({result['timer']} timer, median of {result['frames']})")
    ax.set_title(
        f"Shade-composite time vs light count, {result['size']}x{result['size']}\n{result['device']}", fontsize=9
    )
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _table(result: dict) -> str:
    lines = [
        f"{'lights':>7} {'on ms':>10} {'off ms':>10} {'off/on':>8} {'tile mean':>10} {'tile max':>9} "
        f"{'cull ms':>9} {'tonemap on/off ms':>18} {'SM MHz on/off':>14}"
    ]
    for r in result["results"]:
        on, off = r["on"], r["off"]
        lines.append(
            f"{r['lights']:>7} {on['composite_ms']:>10.3f} {off['composite_ms']:>10.3f} "
            f"{r['ratio_off_on']:>8.2f} {on['tile_lights_mean']:>10.2f} {on['tile_lights_max']:>9} "
            f"{on['light_culling_ms']:>9.3f} "
            f"{on.get('tone_mapping_ms', float('nan')):>8.3f} /{off.get('tone_mapping_ms', float('nan')):>8.3f} "
            f"{str(on.get('sm_clock_mhz', '-')):>6} /{str(off.get('sm_clock_mhz', '-')):>6}"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--lights", type=int, nargs="+", default=DEFAULT_LIGHTS)
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--tile", type=int, default=16)
    ap.add_argument("--per-process", action="store_true", help="measure each light count in a fresh process")
    ap.add_argument("--tile-bits", default="auto", choices=("auto", "cache", "fetch"))
    a = ap.parse_args(argv)
    result = (run_per_process if a.per_process else run)(
        a.out, a.size, sorted(set(a.lights)), a.frames, a.warmup, a.tile, a.tile_bits
    )
    print(
        f"\n{result['device']}, {a.size}x{a.size}, culling {result['culling_mode']}, {result['timer']} timer, "
        f"median of {a.frames} after {a.warmup} warm-up; composite pass:"
    )
    print(_table(result))
    ratio = result["ratio_off_on_at_1024"]
    print(f"off/on composite-time ratio at 1024 lights: {ratio if ratio is not None else 'n/a (1024 not measured)'}")
    print(f"wrote {a.out / 'light_culling.json'} and {a.out / 'light_culling.png'} ({result['elapsed_s']} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
