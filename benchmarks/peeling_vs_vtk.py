"""Dual depth peeling against VTK's on the same scene (llvmpipe or any EGL device).

Usage: python benchmarks/peeling_vs_vtk.py [--out DIR] [--size 512] [--layers 48] [--frames 3]
       [--warmup 1] [--rounds 3] [--methods dual_depth_peeling presort_lf_et] [--threshold T ...]
       [--max-passes N ...] [--vtk-max-peels N ...] [--no-vtk] [--replot]

Scene: LAYERS screen-covering quads (12 x 12 at z = 2 ... -3, distinct hues, alpha 0.5, unlit),
submitted in a shuffled order (seed 7), camera at z = 5 looking at the origin (fov 50, near 0.1,
far 100), no opaque surface. Every pixel has LAYERS layers.

guaca_py renders it through pipelines/exact.yaml (linear output, early-termination threshold
0.999 unless --threshold says otherwise) with each method of --methods; --max-passes adds
dual_depth_peeling runs capped at that many geometry passes (a first pass that finds each pixel's
two ends, then one pass per two layers; what is left is dropped and reported as truncated). VTK (optional: skipped
with a message when `import vtk` fails; never a dependency of the project) renders the same world
triangles with lighting off, one actor per quad in the same submission order, through its dual
depth peeling (vtkRenderer.SetUseDepthPeeling(1), MaximumNumberOfPeels = LAYERS + 2,
OcclusionRatio 0, no multisampling; --vtk-max-peels adds runs with VTK's cap lowered, e.g. to its
default of 4: an initial depth pass, that many peels, and one pass that blends whatever is left
unsorted), once through the renderer's default translucent path and
once through an explicit vtkRenderStepsPass whose translucent pass is a vtkDualDepthPeelingPass.
VTK's window is EGL (VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow, set here unless already set); each
VTK configuration runs in a child process (two EGL contexts in one thread disturb each other), which
measures its own frames; the parent interleaves the configurations round by round.

Timed per frame (wall clock, and process CPU time of all threads): for guaca_py,
Renderer.render(scene, W, H, stats=False), which builds the draw list, runs every pass and reads
the 8-bit image back to numpy (glReadPixels waits for the GPU); for VTK, RenderWindow.Render()
followed by GetPixelData() of the whole window (glReadPixels, same wait). Configurations are
interleaved round by round (rounds x frames timed frames each, after warm-up frames) and the
median is reported (wall time: on llvmpipe both renderers run on the CPU). Error: against
guaca_py.reference's float64 CPU composite of the same triangles, on non-edge pixels, in 1/255
(RMSE and max). The Markdown ends with the comparisons of ours against VTK (ratio of the medians):
each of ours (default, every --threshold, capped) against each VTK run: threshold 1 peels every
layer, as VTK's uncapped run does (the same work).

Writes benchmarks/results/<device>/peeling_vs_vtk/peeling_vs_vtk.{json,md}.
"""

from __future__ import annotations

import argparse
import colorsys
import json
import os
import platform
import resource
import statistics
import sys
import time

import numpy as np

from guaca_py import Renderer
from guaca_py.benchmarking import Progress, Results, bench_args, open_device
from guaca_py.reference import compare, quad_mesh, reference_of, scene_triangles
from guaca_py.scene.graph import Camera, MaterialInstance, Node, Scene, Transform


def planes_scene(n: int, alpha: float = 0.5, seed: int = 7) -> Scene:
    """n screen-covering unlit quads from z=2 (front) to z=-3, shuffled submission order."""
    nodes = []
    for i in range(n):
        z = 2.0 - 5.0 * i / max(n - 1, 1)
        rgb = [float(c) for c in colorsys.hsv_to_rgb(i / n, 0.8, 0.95)]
        nodes.append(
            Node(
                f"p{i:03d}",
                Transform((0.0, 0.0, z), (0.0, 0.0, 0.0)),
                quad_mesh(6.0, 6.0),
                MaterialInstance("unlit", {"color": rgb, "alpha": alpha}),
            )
        )
    order = np.random.default_rng(seed).permutation(n)
    return Scene(
        camera=Camera(position=(0, 0, 5), target=(0, 0, 0), fov_y=50, near=0.1, far=100),
        background=(0.05, 0.08, 0.12),
        nodes=[nodes[i] for i in order],
    )


def cpu_seconds() -> float:
    """User and system CPU time of this process, all threads."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class Ours:
    """One guaca_py renderer (exact pipeline) for one method, with setting overrides (named in the label)."""

    def __init__(self, ctx, method: str, overrides: dict | None = None):
        self.label = " ".join([method, *(f"{k}={v:g}" for k, v in (overrides or {}).items())])
        self.renderer = Renderer("exact", ctx=ctx, method=method, method_overrides=overrides or None)
        self.info: dict = {}

    def frame(self, scene, size: int) -> np.ndarray:
        return self.renderer.render(scene, size, size, stats=False).image

    def describe(self, scene, size: int) -> dict:
        s = self.renderer.render(scene, size, size).stats
        return {
            "geometry_passes": s.get("geometry_passes"),
            "fragments": s.get("fragments"),
            "memory_bytes": sum(v for k, v in s.get("memory", {}).items() if not k.endswith("_used")),
        }


class Vtk:
    """VTK's dual depth peeling of the same triangles (default translucent path or an explicit pass)."""

    def __init__(self, vtk, scene: Scene, size: int, explicit: bool, max_peels: int = 0):
        tris, rgb, alpha = scene_triangles(scene)
        peels = max_peels or len(tris) // 2 + 2
        self.label = "VTK dual depth peeling" + (" (explicit vtkDualDepthPeelingPass)" if explicit else " (default)")
        if max_peels:
            self.label += f" max_peels={max_peels}"
        cam = scene.camera
        rw = vtk.vtkRenderWindow()
        rw.SetOffScreenRendering(1)
        rw.SetMultiSamples(0)
        rw.SetAlphaBitPlanes(1)
        rw.SetSize(size, size)
        ren = vtk.vtkRenderer()
        ren.SetBackground(*scene.background)
        ren.SetUseDepthPeeling(1)
        ren.SetMaximumNumberOfPeels(peels)
        ren.SetOcclusionRatio(0.0)
        rw.AddRenderer(ren)
        for k in range(0, len(tris), 2):  # two triangles per quad, in submission order
            pts = vtk.vtkPoints()
            polys = vtk.vtkCellArray()
            for t in tris[k : k + 2]:
                ids = [pts.InsertNextPoint(*map(float, p)) for p in t]
                polys.InsertNextCell(3, ids)
            pd = vtk.vtkPolyData()
            pd.SetPoints(pts)
            pd.SetPolys(polys)
            mapper = vtk.vtkPolyDataMapper()
            mapper.SetInputData(pd)
            actor = vtk.vtkActor()
            actor.SetMapper(mapper)
            prop = actor.GetProperty()
            prop.LightingOff()
            prop.SetColor(*map(float, rgb[k]))
            prop.SetOpacity(float(alpha[k]))
            ren.AddActor(actor)
        vc = ren.GetActiveCamera()
        vc.SetPosition(*cam.position)
        vc.SetFocalPoint(*cam.target)
        vc.SetViewUp(*cam.up)
        vc.SetViewAngle(cam.fov_y)
        vc.SetClippingRange(cam.near, cam.far)
        if explicit:
            ddp = vtk.vtkDualDepthPeelingPass()
            ddp.SetTranslucentPass(vtk.vtkTranslucentPass())
            ddp.SetMaximumNumberOfPeels(peels)
            ddp.SetOcclusionRatio(0.0)
            steps = vtk.vtkRenderStepsPass()
            steps.SetTranslucentPass(ddp)
            ren.SetPass(steps)
        self.rw, self.ren, self.size = rw, ren, size
        self._pixels = vtk.vtkUnsignedCharArray()
        self.info = {}

    def frame(self, scene, size: int) -> np.ndarray:
        self.rw.Render()
        buf = self._pixels
        self.rw.GetPixelData(0, 0, size - 1, size - 1, 1, buf, 0)
        # vtkUnsignedCharArray (RGB, bottom row first) -> (H, W, 3) top row first
        from vtk.util.numpy_support import vtk_to_numpy

        return np.ascontiguousarray(vtk_to_numpy(buf).reshape(size, size, 3)[::-1])

    def describe(self, scene, size: int) -> dict:
        self.frame(scene, size)
        return {
            "used_depth_peeling": bool(self.ren.GetLastRenderingUsedDepthPeeling()),
            "max_peels": self.ren.GetMaximumNumberOfPeels(),
            "occlusion_ratio": self.ren.GetOcclusionRatio() if hasattr(self.ren, "GetOcclusionRatio") else 0.0,
            "opengl_renderer": self.rw.ReportCapabilities().split("OpenGL renderer string:")[-1].split("\n")[0].strip(),
        }


class VtkProxy:
    """A Vtk configuration living in a child process: VTK's EGL context and ours never share a thread."""

    def __init__(self, args, explicit: bool, max_peels: int = 0):
        import subprocess

        cmd = [sys.executable, __file__, "--vtk-worker", "--size", str(args.size), "--layers", str(args.layers)]
        cmd += ["--max-peels", str(max_peels)] + (["--explicit"] if explicit else [])
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        hello = json.loads(self.proc.stdout.readline())
        self.label = hello["label"]
        self.version = hello["version"]

    def _ask(self, cmd: str) -> dict:
        self.proc.stdin.write(cmd + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

    def frame_image(self) -> np.ndarray:
        r = self._ask("image")
        return np.frombuffer(bytes.fromhex(r["image"]), dtype=np.uint8).reshape(r["shape"])

    def timed(self) -> tuple[float, float]:
        r = self._ask("frame")
        return r["wall_s"], r["cpu_s"]

    def describe(self) -> dict:
        return self._ask("describe")

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def vtk_worker(args) -> None:
    """Serve frames of one Vtk configuration over stdin/stdout (JSON lines)."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import vtk

    scene = planes_scene(args.layers)
    cfg = Vtk(vtk, scene, args.size, explicit=args.explicit, max_peels=args.max_peels)
    print(json.dumps({"label": cfg.label, "version": vtk.vtkVersion.GetVTKVersion()}), flush=True)
    for line in sys.stdin:
        cmd = line.strip()
        if cmd == "image":
            img = cfg.frame(scene, args.size)
            out = {"image": img.tobytes().hex(), "shape": list(img.shape)}
        elif cmd == "frame":
            t0, c0 = time.perf_counter(), cpu_seconds()
            cfg.frame(scene, args.size)
            out = {"wall_s": time.perf_counter() - t0, "cpu_s": cpu_seconds() - c0}
        else:
            out = cfg.describe(scene, args.size)
        print(json.dumps(out), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Compare (or rebuild the table with --replot)."""
    ap = bench_args(__file__, __doc__, size=512, frames=3)
    ap.set_defaults(warmup=1)
    ap.add_argument("--layers", type=int, default=48)
    ap.add_argument("--rounds", type=int, default=3, help="rounds; configurations are interleaved within each")
    ap.add_argument("--methods", nargs="+", default=["dual_depth_peeling", "presort_lf_et"])
    ap.add_argument("--threshold", type=float, nargs="*", default=[], help="extra dual_depth_peeling thresholds")
    ap.add_argument("--max-passes", type=int, nargs="*", default=[], help="extra dual_depth_peeling runs with this cap")
    ap.add_argument("--no-vtk", action="store_true")
    ap.add_argument("--vtk-worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--explicit", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--max-peels", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument(
        "--vtk-max-peels", type=int, nargs="*", default=[], help="extra VTK runs (default path) with these peel caps"
    )
    a = ap.parse_args(argv)
    if a.vtk_worker:
        vtk_worker(a)
        return 0
    if a.replot:
        res = Results.existing(a, argv)
        data = res.read_json()
    else:
        device = open_device()
        res = Results(a, device.name, argv)
        data = run(a, device)
    print(res.finish(data, markdown))
    return 0


def run(a, device) -> dict:
    """Error, then interleaved rounds of timed frames of every configuration; the record."""
    scene = planes_scene(a.layers)
    ref, mask, layers = reference_of(scene, a.size, a.size)
    ctx = device.ctx
    configs: list = [Ours(ctx, m) for m in a.methods]
    configs += [Ours(ctx, "dual_depth_peeling", {"threshold": t}) for t in a.threshold]
    configs += [Ours(ctx, "dual_depth_peeling", {"max_passes": n}) for n in a.max_passes]
    vtk_note = None
    vtk_version = None
    vtk_configs: list = []
    if not a.no_vtk:
        try:
            import vtk  # optional: not a dependency of guaca_py  # noqa: F401
        except ImportError as exc:
            vtk_note = f"VTK not measured: `import vtk` failed ({exc}); pip install vtk to include it"
            print(vtk_note, file=sys.stderr)
        else:
            vtk_configs = [VtkProxy(a, explicit=False), VtkProxy(a, explicit=True)]
            vtk_configs += [VtkProxy(a, explicit=False, max_peels=p) for p in a.vtk_max_peels]
            vtk_version = vtk_configs[0].version
    else:
        vtk_note = "VTK not measured (--no-vtk)"

    rows = {}
    for c in configs:
        err = compare(c.frame(scene, a.size), ref, mask)
        rows[c.label] = {"rmse_255": err["rmse_255"], "max_255": err["max_abs_255"], **c.describe(scene, a.size)}
        for _ in range(a.warmup):
            c.frame(scene, a.size)
    for v in vtk_configs:
        err = compare(v.frame_image(), ref, mask)
        rows[v.label] = {"rmse_255": err["rmse_255"], "max_255": err["max_abs_255"], **v.describe()}
        for _ in range(a.warmup):
            v.timed()
    for row in rows.values():
        row["wall_s"], row["cpu_s"] = [], []
    progress = Progress(a.rounds)
    for r in range(a.rounds):
        for c in configs:
            for _ in range(a.frames):
                t0, c0 = time.perf_counter(), cpu_seconds()
                c.frame(scene, a.size)
                rows[c.label]["wall_s"].append(time.perf_counter() - t0)
                rows[c.label]["cpu_s"].append(cpu_seconds() - c0)
        for v in vtk_configs:
            for _ in range(a.frames):
                w, cpu = v.timed()
                rows[v.label]["wall_s"].append(w)
                rows[v.label]["cpu_s"].append(cpu)
        progress.step(f"round {r + 1} done")
    for v in vtk_configs:
        v.close()
    for row in rows.values():
        row["median_wall_s"] = statistics.median(row["wall_s"])
        row["median_cpu_s"] = statistics.median(row["cpu_s"])
    meta = {
        "cpus": os.cpu_count(),
        "machine": platform.processor() or platform.machine(),
        "vtk": vtk_version,
        "vtk_note": vtk_note,
        "size": a.size,
        "layers": a.layers,
        "max_depth_complexity": int(layers.max()),
        "frames_per_round": a.frames,
        "rounds": a.rounds,
        "warmup": a.warmup,
        "load_average": os.getloadavg(),
    }
    return {"meta": meta, "rows": rows}


def markdown(data: dict) -> str:
    """The table: wall and CPU seconds per frame, geometry passes and error of each configuration."""
    meta, rows = data["meta"], data["rows"]
    lines = [
        f"{meta['layers']} shuffled screen-covering quads (alpha 0.5, unlit), {meta['size']}², {data['device']}, "
        f"{meta['cpus']} CPUs, load average at the end {', '.join(f'{x:.2f}' for x in meta['load_average'])}. "
        f"Median of {meta['rounds']} interleaved rounds x {meta['frames_per_round']} frames after "
        f"{meta['warmup']} warm-up; a frame "
        "includes the read-back of the 8-bit image. CPU = process CPU time of all threads per frame. "
        "Error against the float64 CPU composite, non-edge pixels, 1/255. Layers dropped: per pixel, what "
        "ours leaves out under max_passes (reported as truncated); VTK's cap of N peels blends what its "
        "N peels leave unsorted in one more pass instead.",
        "",
        "| configuration | wall s/frame | CPU s/frame | geometry passes | layers dropped | RMSE / max (1/255) |",
        "|---|---|---|---|---|---|",
    ]
    pixels = meta["size"] ** 2
    for label, row in rows.items():
        passes = row.get("geometry_passes", "")
        truncated = (row.get("fragments") or {}).get("truncated")
        dropped = "" if truncated is None else f"{truncated / pixels:g}"
        lines.append(
            f"| {label} | {row['median_wall_s']:.3f} | {row['median_cpu_s']:.3f} | {passes} | {dropped} | "
            f"{row['rmse_255']:.2f} / {row['max_255']:.1f} |"
        )
    lines += comparisons(rows)
    if meta.get("vtk_note"):
        lines += ["", meta["vtk_note"]]
    lines += ["", f"Command: `{data['command']}`", ""]
    return "\n".join(lines)


def comparisons(rows: dict) -> list[str]:
    """Markdown lines: each dual_depth_peeling run (default, other thresholds, capped) against each VTK run, medians' ratios."""
    ours = [k for k in rows if k == "dual_depth_peeling" or k.startswith("dual_depth_peeling ")]
    vtk = [k for k in rows if k.startswith("VTK")]
    if not ours or not vtk:
        return []
    lines = [
        "",
        "| ours | VTK | wall ours / VTK | CPU ours / VTK | ours no slower (wall) |",
        "|---|---|---|---|---|",
    ]
    for o in ours:
        for v in vtk:
            wall = rows[o]["median_wall_s"] / rows[v]["median_wall_s"]
            cpu = rows[o]["median_cpu_s"] / rows[v]["median_cpu_s"]
            lines.append(f"| {o} | {v} | {wall:.2f} | {cpu:.2f} | {'yes' if wall <= 1.0 else 'no'} |")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
