"""Cost against the work: frame size, a stereo pair against one frame of both views, a field of models.

Run as `python benchmarks/paper_table.py scaling [options]` (benchmarks/README.md). Every row is one
scene through one method and one rasterizer setting, measured the same way:

- loop wall: mean wall time per frame of --frames renders without read-back or timers
  (`render(read_back=False, stats=False)`, or `render_views` for a stereo pair), from an idle GPU
  (`ctx.finish()`) to the last frame's end, after a warm-up; rows whose sampled SM clock was under
  90% of the maximum are measured again (clock.at_full_clock);
- one timed frame after it (read back): GPU time per pass, fragments stored, overflow and drops,
  the transparent pool (bytes, bytes per node), which rasterizer drew what; the compute
  rasterizer's per-stage times come from a second renderer with its stage profile on (profile_stages)
  (reading them waits for the GPU, so the measured renderer never has them);
- ns per stored fragment: the loop wall over the fragments stored.

Parts: every --scene-names scene at every --sizes (square frames); the --stereo-scene as a stereo
pair of --stereo-size² views (Renderer.render_views) against one --stereo-size x 2·--stereo-size
frame; fields of --field copies of the --field-scene's first mesh file at --size², written as
field_<n>.yaml into --field-dir (default: a temporary folder; one mesh file, read once, uploaded once). Rows left when
--budget-s is spent are recorded as skipped; a row whose frames are slow takes fewer loop frames
(--row-s) and says so.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import moderngl

from ..errors import GuacaError
from ..methods import auto
from ..renderer import Renderer
from ..scene.graph import Camera, Scene
from ..scene.loader import load_scene
from ..scene.views import stereo_pair
from .clock import at_full_clock, below_max_clock, max_sm_clock
from .harness import Progress, Results, bench_args, header, open_device, raster_overrides, timer_of
from .scenes import write_field

NAME = "scaling"
SIZES = (512, 1024, 2048, 2560, 3072, 3584, 4096)
SCENES = ("dragons", "hairball_v1")
FIELD = (1, 4, 16, 64)
RASTERS = ("auto", "hardware")
FIRST_METHOD = "presort_lf_et"
STEREO_TOLERANCE = 0.10  # a stereo pair's ns per stored fragment within 10% of one frame of both views
POOL_PER_STORED_MAX = 1.2  # a pool's bytes over its stored nodes' after a steady frame (issue 25's memory line)
_OWN = {"restore_host_state": False}  # the benchmark's own context: no host state to keep


def next_exact_method(first: str = FIRST_METHOD) -> str:
    """The exact method methods/auto.py's NVIDIA table ranks fastest after `first`."""
    return next(m for m, _ in auto.NVIDIA.ranking() if m != first)


@dataclass
class Job:
    """One row to measure: a scene (loaded on first use), a frame size, and the views, if several."""

    part: str  # "size", "stereo" or "field"
    scene: str  # the scene's name in the record
    method: str
    raster: str
    width: int
    height: int
    views: int = 1  # > 1: a stereo pair of the scene camera through render_views
    count: int | None = None  # copies in a field
    row: dict = field(default_factory=dict)

    def draw(self, renderer: Renderer, scene: Scene, cameras: list[Camera] | None, **kw) -> list:
        """The frame (render) or frames (render_views) of this row."""
        if cameras:
            return renderer.render_views(scene, cameras, self.width, self.height, **kw)
        return [renderer.render(scene, self.width, self.height, **kw)]


class Renderers:
    """A renderer per (method, raster), kept across rows (programs compile once); stage-timing twins on demand."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._made: dict[tuple[str, str, bool], Renderer] = {}

    def get(self, method: str, raster: str, stages: bool = False) -> Renderer:
        """The renderer of `method` through `raster` ('compute/tile': with that raster_order; `stages`: its
        twin whose compute rasterizer times stages)."""
        key = (method, raster, stages)
        if key not in self._made:
            overrides = raster_overrides(raster)
            r = self._made[key] = Renderer("default", ctx=self.ctx, method=method, method_overrides=overrides, **_OWN)
            r.raster.compute.profile_stages(stages)
        return self._made[key]

    def release(self) -> None:
        """Release every renderer made."""
        for r in self._made.values():
            r.release()
        self._made.clear()


def plan(args: argparse.Namespace) -> list[Job]:
    """Every row, in the order measured: frame sizes scene by scene, the stereo pair, the fields."""
    configs = [(m, r) for m in args.methods for r in args.raster]
    jobs = [Job("size", s, m, r, n, n) for s in args.scene_names for n in args.sizes for m, r in configs]
    if args.stereo_size:
        n = args.stereo_size
        for m, r in configs:
            jobs += [
                Job("stereo", args.stereo_scene, m, r, n, n, views=2),
                Job("stereo", args.stereo_scene, m, r, n, 2 * n),
            ]
    jobs += [Job("field", f"field_{c}", m, r, args.size, args.size, count=c) for c in args.field for m, r in configs]
    return jobs


class SceneStore:
    """Scenes loaded on first use: the scene files of --scenes, and fields written into the results folder."""

    def __init__(self, args: argparse.Namespace, out_dir: Path, progress: Progress):
        self.args, self.out_dir, self.progress = args, out_dir, progress
        self._loaded: dict[str, Scene] = {}

    def source(self, name: str) -> Path:
        """The scene file `name` of --scenes (SystemExit naming it when missing)."""
        path = self.args.scenes / f"{name}.yaml"
        if not path.is_file():
            raise SystemExit(
                f"{path}: no such scene (copy ../shared/scenes to .scenes/; make_hairball.py writes the hairball)"
            )
        return path

    def get(self, job: Job) -> Scene:
        """The scene of `job`, loading (and for a field, writing) it the first time."""
        if job.scene not in self._loaded:
            t0 = time.perf_counter()
            if job.count is None:
                self._loaded[job.scene] = load_scene(self.source(job.scene))
            else:
                src = self.source(self.args.field_scene)
                base = self._loaded.get(self.args.field_scene) or load_scene(src)
                self._loaded[self.args.field_scene] = base
                self._loaded[job.scene] = load_scene(write_field(src, base, job.count, self.out_dir))
            self.progress.note(f"{job.scene}: loaded in {time.perf_counter() - t0:.1f} s")
        return self._loaded[job.scene]


def _sum_passes(frames: list) -> dict[str, float]:
    """Per pass, the ms of all the frames' (all views of a call) together."""
    out: dict[str, float] = {}
    for f in frames:
        for name, p in f.stats["passes"].items():
            out[name] = out.get(name, 0.0) + p["ms"]
    return out


def _summary(frames: list) -> dict:
    """What one timed frame (or the views of one call) says: passes, fragments, pool, drops, rasterizers."""
    stats = [f.stats for f in frames]
    fr = [s.get("fragments", {}) for s in stats]
    comp = [s.get("raster", {}).get("compute") or {} for s in stats]
    mem = stats[0].get("memory", {})  # the views share the pool: the first view's is the call's
    pool, node = mem.get("abuffer_pool"), mem.get("abuffer_node_bytes")
    passes = _sum_passes(frames)
    return {
        "timer": stats[0].get("timer"),
        "passes_ms": passes,
        "total_ms": sum(passes.values()),
        "stored": sum(f.get("stored", 0) for f in fr),
        "overflow": sum(f.get("overflow", 0) for f in fr),
        "dropped": sum(f.get("guard_abandoned", 0) + f.get("lock_abandoned", 0) for f in fr)
        + sum(c.get("large_dropped", 0) + c.get("tile_jobs_dropped", 0) for c in comp),
        "pool_bytes": pool,
        "pool_used_bytes": mem.get("abuffer_pool_used"),
        "bytes_per_node": node,
        "pool_nodes": pool // node if pool and node else None,
        "drew": {k: sum(s.get("raster", {}).get(f"{k}_draws", 0) for s in stats) for k in ("compute", "hardware")},
        "raster_order": next((c["order"] for c in comp if c.get("order")), None),  # the compute rasterizer's
        "regrown": sum(s.get("regrown", 0) for s in stats),
        "warnings": sorted({w for s in stats for w in s.get("warnings", [])}),
    }


def measure(job: Job, renderers: Renderers, scene: Scene, args: argparse.Namespace) -> dict:
    """Loop wall, one timed frame and (compute rasterizer drawing) its stage times; the row's figures."""
    r = renderers.get(job.method, job.raster)
    cameras = stereo_pair(scene.camera, args.eye_separation) if job.views > 1 else None
    uploads = r.meshes.uploads
    t0 = time.perf_counter()
    first = job.draw(r, scene, cameras)  # compiles programs, grows the pool to the scene's need
    first_s = time.perf_counter() - t0
    gpu = first[0].stats.get("timer") == "gpu"
    r.ctx.finish()
    t1 = time.perf_counter()
    job.draw(r, scene, cameras, read_back=False, stats=False)
    r.ctx.finish()
    frame_s = time.perf_counter() - t1
    frames = max(3, min(args.frames, int(args.row_s / max(frame_s, 1e-9))))

    def warm() -> None:
        end, n = time.perf_counter() + (args.warmup_s if gpu else 0.0), 0
        while n < args.warmup or time.perf_counter() < end:
            job.draw(r, scene, cameras, read_back=False, stats=False)
            n += 1
        r.ctx.finish()

    def timed() -> tuple[float, list]:
        r.ctx.finish()
        t = time.perf_counter()
        for _ in range(frames):
            job.draw(r, scene, cameras, read_back=False, stats=False)
        r.ctx.finish()
        wall = (time.perf_counter() - t) * 1e3 / frames
        return wall, job.draw(r, scene, cameras)  # read back: this frame's own times and counters

    (wall, timed_frames), clock, retries = at_full_clock(timed, warm_up=warm)
    row = {"loop_wall_ms": wall, "loop_frames": frames, **_summary(timed_frames)}
    row["ns_per_stored"] = wall * 1e6 / row["stored"] if row["stored"] else None
    row.update(clock=clock.summary(), clock_retries=retries, first_frame_s=first_s)
    row["mesh_uploads"] = r.meshes.uploads - uploads
    row["meshes"] = len({id(n.mesh) for n, _ in scene.walk() if n.mesh is not None})
    if frames < args.frames:
        row["note"] = f"{frames} loop frames: {args.frames} would take over --row-s {args.row_s:g} s"
    if args.stages and row["drew"]["compute"]:
        twin = renderers.get(job.method, job.raster, stages=True)
        job.draw(twin, scene, cameras)  # grows its pool and queues
        staged = job.draw(twin, scene, cameras)
        spans: dict[str, float] = {}
        for f in staged:
            for k, v in (f.stats.get("raster", {}).get("compute", {}).get("stage_ms") or {}).items():
                spans[k] = spans.get(k, 0.0) + v
        row["raster_stage_ms"] = spans
    return row


def run(args: argparse.Namespace, device, res: Results) -> dict:
    """Measure every row of plan(args) (those past --budget-s skipped); the record."""
    jobs = plan(args)
    progress = Progress(len(jobs))
    temporary = tempfile.TemporaryDirectory(prefix="guaca_field_") if args.field_dir is None else None
    scenes = SceneStore(args, args.field_dir or Path(temporary.name), progress)
    renderers = Renderers(device.ctx)
    t0 = time.perf_counter()
    try:
        for job in jobs:
            row = job.row
            row.update(part=job.part, scene=job.scene, method=job.method, raster=job.raster)
            row.update(width=job.width, height=job.height, views=job.views, count=job.count)
            t1 = time.perf_counter()
            if time.perf_counter() - t0 > args.budget_s:
                row["skipped"] = f"time budget spent (--budget-s {args.budget_s:g})"
            else:
                try:
                    row.update(measure(job, renderers, scenes.get(job), args))
                except (GuacaError, moderngl.Error) as exc:
                    row["skipped"] = str(exc)
            row["seconds"] = time.perf_counter() - t1
            progress.step(_line(row))
    finally:
        renderers.release()
        if temporary is not None:
            temporary.cleanup()
    return {
        "sizes": args.sizes,
        "methods": args.methods,
        "rasters": args.raster,
        "frames": args.frames,
        "budget_s": args.budget_s,
        "max_sm_clock_mhz": max_sm_clock(),
        "capabilities": device.caps.as_dict(),
        "rows": [j.row for j in jobs],
    }


def _label(row: dict) -> str:
    views = f" ({row['views']} views)" if row.get("views", 1) > 1 else ""
    return f"{row['scene']} {row['width']}x{row['height']}{views} {row['method']} ({row['raster']})"


def _line(row: dict) -> str:
    """A progress line for a row."""
    if "skipped" in row:
        return f"{_label(row)}: skipped: {row['skipped']}"
    ns = row["ns_per_stored"]
    mhz = row["clock"]["sm_clock_mhz_median"] if row.get("clock") else "—"
    return (
        f"{_label(row)}: loop wall {row['loop_wall_ms']:.3f} ms, stored {row['stored']}, "
        f"{'—' if ns is None else f'{ns:.3f}'} ns/fragment, SM {mhz} MHz"
    )


def pool_per_stored(row: dict) -> float | None:
    """A row's pool bytes over the bytes of the nodes it stored; a call of several views shares one pool, which
    holds one view's nodes at a time: over the mean view's."""
    pool, node = row.get("pool_bytes"), row.get("bytes_per_node")
    if not pool or not node or not row.get("stored"):
        return None
    return pool / (row["stored"] / row.get("views", 1) * node)


def _cells(row: dict, top: float | None) -> list[str]:
    """The table cells after the row's own columns: times, fragments, pool, drops, clock, note."""
    if "skipped" in row:
        return [f"skipped: {row['skipped']}"] + [""] * (len(COLUMNS.split("|")) - 1)
    p = row["passes_ms"]
    other = sum(v for k, v in p.items() if k not in ("geometry", "light_culling", "composite"))
    drew = ", ".join(f"{n} {k}" for k, n in row["drew"].items() if n) or "—"
    ns = row["ns_per_stored"]
    ratio = pool_per_stored(row)
    pool = f"{row['pool_bytes'] / 2**20:.1f} ({row['bytes_per_node']} B)" if row.get("pool_bytes") else "—"
    if ratio is not None:
        pool += f", {ratio:.2f}×"
    clock = row["clock"]["sm_clock_mhz_median"] if row.get("clock") else "—"
    if below_max_clock(row.get("clock"), top):
        clock = f"{clock} (under max)"
    stages = row.get("raster_stage_ms")
    notes = [row.get("note", "")] + (
        [f"stages {', '.join(f'{k} {v:.2f}' for k, v in stages.items())}"] if stages else []
    )
    if row["part"] == "field":  # the copies share one mesh: read once, uploaded at most once per renderer
        notes.append(f"{row['meshes']} mesh, {row['mesh_uploads']} new upload(s)")
    return [
        drew,
        f"**{row['loop_wall_ms']:.3f}**",
        f"{p.get('geometry', 0):.3f} / {p.get('light_culling', 0):.3f} / {p.get('composite', 0):.3f} / {other:.3f}",
        str(row["stored"]),
        "—" if ns is None else f"**{ns:.3f}**",
        pool,
        f"{row['overflow']} / {row['dropped']}",
        str(clock),
        "; ".join(n for n in notes if n),
    ]


COLUMNS = (
    "drew | loop wall ms | GPU ms: geometry / light culling / composite / other | stored | ns / stored "
    "| pool MiB (per node), ÷ stored | overflow / drops | SM MHz | note"
)


def markdown(rec: dict) -> str:
    """scaling.md: the three parts as tables, and the stereo pair against one frame."""
    rows, top = rec["rows"], rec.get("max_sm_clock_mhz")
    lines = header("Cost against the work", rec["device"], rec["command"], timer_of(rows))
    lines += [
        f"Loop wall: mean of {rec['frames']} frames rendered without read-back or timers, from an idle GPU "
        "to the last frame's end; GPU ms: one timed frame after it (a stereo pair: both views); "
        "ns / stored: loop wall over the fragments stored. `drew`: draws through each rasterizer.",
        "",
    ]
    parts = (
        ("size", "Frame size", "scene | size"),
        ("stereo", "A stereo pair (render_views) against one frame of both views' pixels", "scene | frame"),
        ("field", "A field of copies of one mesh", "copies | size"),
    )
    for part, title, first in parts:
        these = [r for r in rows if r["part"] == part]
        if not these:
            continue
        head = f"| {first} | method | raster | {COLUMNS} |"
        lines += [f"## {title}", "", head, "|" + "---|" * (head.count("|") - 1)]
        for r in these:
            what = r["count"] if part == "field" else r["scene"]
            size = f"{r['width']}x{r['height']}" + (f", {r['views']} views" if r.get("views", 1) > 1 else "")
            lines.append(f"| {what} | {size} | {r['method']} | {r['raster']} | " + " | ".join(_cells(r, top)) + " |")
        lines.append("")
        if part == "stereo":
            lines += stereo_lines(these, top)
    lines += memory_lines(rows)
    return "\n".join(lines) + "\n"


def memory_lines(rows: list[dict]) -> list[str]:
    """The rows whose pool holds more than POOL_PER_STORED_MAX times the bytes of the nodes it stored."""
    over = [(r, ratio) for r in rows if (ratio := pool_per_stored(r) or 0) > POOL_PER_STORED_MAX]
    lines = [f"Pools over {POOL_PER_STORED_MAX}× the bytes of the nodes they stored (÷ stored):", ""]
    for r, ratio in over:
        what = f"{r['count']} copies" if r["part"] == "field" else r["scene"]
        lines.append(f"- {what}, {r['width']}x{r['height']}, {r['method']} ({r['raster']}): {ratio:.2f}×")
    return lines + (["- none"] if not over else []) + [""]


def stereo_ratios(rows: list[dict]) -> list[tuple[str, str, float | None]]:
    """(method, raster, the pair's ns per stored fragment over one frame's) for each configuration measured both ways."""
    out = []
    for pair in (r for r in rows if r.get("views", 1) > 1 and r.get("ns_per_stored")):
        one = next(
            (
                r
                for r in rows
                if r.get("views", 1) == 1
                and (r["method"], r["raster"]) == (pair["method"], pair["raster"])
                and r.get("ns_per_stored")
            ),
            None,
        )
        out.append((pair["method"], pair["raster"], pair["ns_per_stored"] / one["ns_per_stored"] if one else None))
    return out


def stereo_lines(rows: list[dict], top: float | None) -> list[str]:
    """The pair against one frame: ratio of ns per stored fragment, and whether it is within STEREO_TOLERANCE."""
    lines = [f"Pair over one frame, ns per stored fragment (target: within {STEREO_TOLERANCE:.0%}):", ""]
    for method, raster, ratio in stereo_ratios(rows):
        if ratio is None:
            lines.append(f"- {method} ({raster}): one of the two was not measured")
            continue
        ok = "within" if abs(ratio - 1) <= STEREO_TOLERANCE else "**outside**"
        lines.append(f"- {method} ({raster}): {ratio:.3f}, {ok} the target")
    return lines + [""]


def chart(rec: dict):
    """A drawing function: ns per stored fragment against frame size (and against field copies)."""
    rows = [r for r in rec["rows"] if r.get("ns_per_stored")]
    timer = timer_of(rows)

    def draw(plt):
        parts = (
            (
                [r for r in rows if r["part"] == "size"],
                "width",
                "frame size (px, square)",
                ("scene", "method", "raster"),
            ),
            (
                [r for r in rows if r["part"] == "field"],
                "count",
                f"copies at {rec.get('field_size', '?')}²",
                ("method", "raster"),
            ),
        )
        if not any(these for these, *_ in parts):
            return None
        fig, axes = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [3, 2]})
        for ax, (these, x, xlabel, keys) in zip(axes, parts):
            for key in dict.fromkeys(tuple(r[k] for k in keys) for r in these):
                pts = sorted((r[x], r["ns_per_stored"]) for r in these if tuple(r[k] for k in keys) == key)
                ax.plot(*zip(*pts), "o-" if key[-1] == "auto" else "s--", label=f"{' '.join(key[:-1])} ({key[-1]})")
            ticks = sorted({r[x] for r in these})
            if ticks:
                ax.set_xscale("log", base=2)
                ax.set_xticks(ticks, [str(t) for t in ticks])
                ax.legend(fontsize=7)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("ns per stored fragment (loop wall time)")
            ax.set_ylim(bottom=0)
            ax.grid(True, alpha=0.3)
        soft = " (a software rasterizer: CPU time, no GPU figure)" if timer == "wall" else ""
        axes[0].set_title(f"{rec['device']}{soft}: cost per stored fragment against frame size", fontsize=9)
        axes[1].set_title("against the number of models (one mesh, shared)", fontsize=9)
        fig.tight_layout()
        return fig

    return draw


def parser(script: str) -> argparse.ArgumentParser:
    """The arguments of `paper_table.py scaling`."""
    ap = bench_args(script, __doc__, size=1024, frames=30, scenes=True)
    ap.prog, ap.description = (
        "paper_table.py scaling",
        "How cost grows with the work: frame size, a stereo pair, a field of models.",
    )
    shared = {"size": "the field part's frame width and height", "frames": "frames of each row's loop (mean)"}
    for action in ap._actions:  # the common arguments, as this benchmark uses them
        action.help = shared.get(action.dest, action.help)
    ap.set_defaults(scene_names=list(SCENES), warmup_s=0.5)
    ap.add_argument("--sizes", type=int, nargs="*", default=list(SIZES), help="square frame sizes of the size part")
    ap.add_argument("--methods", nargs="*", default=[FIRST_METHOD, next_exact_method()])
    ap.add_argument(
        "--raster",
        nargs="*",
        default=list(RASTERS),
        help="transparency.raster settings; compute/ORDER also sets raster_order",
    )
    ap.add_argument("--stereo-scene", default="dragons", help="scene of the stereo part")
    ap.add_argument("--stereo-size", type=int, default=2048, help="each stereo view's size (0: no stereo part)")
    ap.add_argument("--eye-separation", type=float, default=0.3, help="stereo eye separation in scene units")
    ap.add_argument("--field", type=int, nargs="*", default=list(FIELD), help="copies in each field (--size² frames)")
    ap.add_argument("--field-scene", default="dragons", help="scene whose first mesh file the field repeats")
    ap.add_argument("--field-dir", type=Path, help="where the field scenes are written (default: a temporary folder)")
    ap.add_argument("--budget-s", type=float, default=225.0, help="rows started after this many seconds are skipped")
    ap.add_argument("--row-s", type=float, default=6.0, help="fewer loop frames where --frames would take longer")
    ap.add_argument("--no-stages", dest="stages", action="store_false", help="no compute-rasterizer stage times")
    return ap


def main(script: str, argv: list[str]) -> int:
    """`paper_table.py scaling ARGS`: measure (or --replot) and write benchmarks/results/<device>/paper_table/scaling.*."""
    args = parser(script).parse_args(argv)
    command_argv = [NAME, *argv]
    if args.replot:
        res = Results.existing(args, command_argv, name=NAME)
        rec = res.read_json()
    else:
        device = open_device()
        res = Results(args, device.name, command_argv, name=NAME)
        rec = run(args, device, res)
        rec["field_size"] = args.size
        device.release()
    res.finish(rec, markdown, chart)
    return 0
