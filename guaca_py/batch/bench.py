"""What a batch job costs against a plain loop: frames per second, time to the first frame, identical images.

    python -m guaca_py.batch.bench [--scene SCENE] [--size 256] [--frames 48] [--workers 1 2] [--ray] [--out DIR]

The job is a turntable of the scene (an orbit from its camera, `camera: {orbit: {}}`) at
size x size with the default pipeline. The plain loop is one Renderer in this process calling
`render(read_back=True)` per camera; each batch run renders the same job with N local workers
into a fresh folder (PNGs, manifest). Steady rates leave the first frame out (program
compilation, worker start); the time to the first frame counts from the call, scene loading
included. Every batch image is checked against the plain loop's pixels. Also measured: PNG
encoding and the atomic write per frame on one thread, and with --ray the round trip of a Ray
actor call (empty, and returning 1 MiB). Writes <out>/batch.json and batch.md (default
benchmarks/results/<device>/batch/).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shlex
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

PNG_LEVELS = (1, 6)  # the batch default, and FrameResult.save's


def _pixels_digest(image: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(image).tobytes()).hexdigest()


def plain_loop(scene_path: Path | None, job, size: int, check: bool = True) -> dict:
    """The plain loop: load, one Renderer, `render(read_back=True)` per frame.

    `check`: then, untimed, the digest of every image and the costs of encoding and writing PNGs.
    """
    from ..output import write_atomic
    from ..renderer import Renderer
    from ..scene.graph import Camera
    from ..scene.loader import demo_scene
    from ..scene.loader import load as load_any
    from .plan import cameras
    from .worker import encode_png

    t0 = time.perf_counter()
    scene = load_any(scene_path) if scene_path else demo_scene()
    cams = cameras(job, scene)
    r = Renderer("default")
    times, digests, images, first_pass, run_to_run = [], [], [], [], 0
    try:
        for cam in cams:  # timed: nothing but the frames (each read back, as the loop's images)
            scene.camera = Camera(**cam)
            frame = r.render(scene, size, size)
            times.append(time.perf_counter())
            if check:
                first_pass.append(frame.image)
        device, timer = frame.stats["device"], frame.stats["timer"]
        for i, cam in enumerate(cams if check else []):  # again, untimed: what each image must be
            scene.camera = Camera(**cam)
            image = r.render(scene, size, size).image
            digests.append(_pixels_digest(image))
            # the same frame twice: a GPU's fragment order varies, and early termination with it
            run_to_run = max(run_to_run, int(np.abs(image.astype(int) - first_pass[i].astype(int)).max()))
            first_pass[i] = image
            if i < 8:
                images.append(image)
    finally:
        r.release()
    encode: dict[int, list[float]] = {level: [] for level in PNG_LEVELS}
    write = []
    with tempfile.TemporaryDirectory() as tmp:
        for i, img in enumerate(images[1:] or images):  # none without `check`
            for level in PNG_LEVELS:
                t = time.perf_counter()
                png = encode_png(img, level)
                encode[level].append(time.perf_counter() - t)
            t = time.perf_counter()
            write_atomic(Path(tmp) / f"{i}.png", lambda p, png=png: p.write_bytes(png))
            write.append(time.perf_counter() - t)
    n = len(times)
    return {
        "device": device,
        "timer": timer,
        "frames": n,
        "first_frame_s": times[0] - t0,
        "wall_s": times[-1] - t0,
        "fps": n / (times[-1] - t0),
        "steady_fps": (n - 1) / (times[-1] - times[0]) if n > 1 else None,
        "digests": digests,
        "reference": first_pass,  # the check pass's images (not written to JSON)
        "run_to_run_max_diff": run_to_run if check else None,
        **(
            {
                "png_encode_ms": {level: 1e3 * statistics.median(t) for level, t in encode.items()},
                "png_kib": {level: len(encode_png(images[-1], level)) / 1024 for level in PNG_LEVELS},
                "write_ms": 1e3 * statistics.median(write),
            }
            if check
            else {}
        ),
    }


def batch_run(job, workers: int, expected: list[str], reference: list | None = None) -> dict:
    """One `render_job` of the job with `workers` local workers into a fresh folder; its rates and whether it matches."""
    from PIL import Image

    from .run import render_job

    stamps: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        t0 = time.perf_counter()
        result = render_job(
            job, out, workers=workers, progress=False, on_frame=lambda line: stamps.append(time.perf_counter())
        )
        wall = time.perf_counter() - t0
        lines = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
        pixels = {line["frame"]: np.asarray(Image.open(out / line["file"]).convert("RGB")) for line in lines}
        got = {i: _pixels_digest(img) for i, img in pixels.items()}
        mismatched = [i for i, d in enumerate(expected) if got.get(i) != d]
        max_diff = (
            max(
                (
                    int(np.abs(pixels[i].astype(int) - reference[i].astype(int)).max())
                    for i in mismatched
                    if i in pixels
                ),
                default=0,
            )
            if reference
            else None
        )
    n = len(stamps)
    return {
        "workers": workers,
        "frames": result.rendered,
        "wall_s": wall,
        "first_frame_s": result.first_frame_s,
        "fps": result.rendered / wall,
        "steady_fps": (n - 1) / (stamps[-1] - stamps[0]) if n > 1 and stamps[-1] > stamps[0] else None,
        "identical": not mismatched,
        "mismatched_frames": mismatched,
        "max_diff": max_diff,  # in 1/255, against the plain loop's images
    }


def _medians(records: list[dict]) -> dict:
    """The first record with each rate and time replaced by its median over all records (their values kept beside)."""
    out = dict(records[0])
    for key in ("steady_fps", "fps", "first_frame_s", "wall_s"):
        values = [r[key] for r in records if r.get(key) is not None]
        if values:
            out[key] = statistics.median(values)
            out[key + "_runs"] = values
    return out


def ray_overhead(calls: int = 200) -> dict:
    """Round trip of a Ray actor method on a local instance: empty, and returning 1 MiB (ms, medians)."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    try:

        @ray.remote
        class Echo:
            def ping(self, n: int = 0) -> bytes:
                return b"x" * n

        actor = Echo.remote()
        ray.get(actor.ping.remote())
        out = {}
        for label, n in (("empty", 0), ("1MiB", 2**20)):
            times = []
            for _ in range(calls):
                t = time.perf_counter()
                ray.get(actor.ping.remote(n))
                times.append(time.perf_counter() - t)
            out[f"ray_call_{label}_ms"] = 1e3 * statistics.median(times)
        out["ray_version"] = ray.__version__
        return out
    finally:
        ray.shutdown()


def markdown(rec: dict) -> str:
    """The results as a Markdown page."""
    p = rec["plain"]
    title = f"Batch rendering against the plain loop: {rec['scene']} turntable, {rec['size']}², {rec['frames']} frames"
    lines = [f"# {title}", "", f"Device: {p['device']}.", "", f"Command: `{rec['command']}`", ""]
    lines += [
        f"Plain loop: one Renderer in one process, `render(read_back=True)` per frame (no PNG). Batch: `render_job` "
        f"with N local worker processes writing PNGs and the manifest. Steady rates leave the first frame out; "
        f"the first frame counts from the call (scene loading, worker start, program compilation included). "
        f"Times are wall-clock ({'frames rendered on the GPU' if p['timer'] == 'gpu' else 'llvmpipe renders on the CPU'}). "
        f"Machine: {rec['cpus']} CPU cores, load average {rec['load_before']:.1f} before the run. "
        f"Medians of {rec['repeat']} interleaved run(s) of each configuration.",
        "",
        "| run | frames/s (steady) | frames/s (whole call) | first frame s | vs plain loop (steady) | images |",
        "|---|---|---|---|---|---|",
        f"| plain loop | {p['steady_fps']:.2f} | {p['fps']:.2f} | {p['first_frame_s']:.2f} | 1.000 | reference |",
    ]
    for b in rec["batch"]:
        rel = b["steady_fps"] / p["steady_fps"] if b["steady_fps"] else float("nan")
        same = "identical" if b["identical"] else f"differ by at most {b.get('max_diff')}/255 in some run"
        lines.append(
            f"| batch, {b['workers']} worker(s) | {b['steady_fps']:.2f} | {b['fps']:.2f} | {b['first_frame_s']:.2f} "
            f"| {rel:.3f} | {same} |"
        )
    if p.get("run_to_run_max_diff") is not None:
        lines += [
            "",
            f"The plain loop's own images, the same frame rendered twice, differ by at most "
            f"{p['run_to_run_max_diff']}/255: on a GPU the order in which fragments reach the A-buffer changes "
            "from run to run, and with it which ones early termination drops behind the threshold. The batch "
            "counts as matching when it is identical or, on a GPU, within the larger of that bound and 1/255.",
        ]
    lines += [
        "",
        "Per frame on one thread of this machine: PNG encoding "
        + ", ".join(
            f"{p['png_encode_ms'][level]:.2f} ms at level {level} ({p['png_kib'][level]:.0f} KiB)"
            for level in PNG_LEVELS
        )
        + f" (batch jobs write level 1 unless told); atomic write (temporary file, fsync, rename) {p['write_ms']:.2f} ms.",
    ]
    if "ray" in rec:
        r = rec["ray"]
        lines += [
            "",
            f"Ray {r['ray_version']} actor call round trip (local instance, median of 200): empty "
            f"{r['ray_call_empty_ms']:.2f} ms, returning 1 MiB {r['ray_call_1MiB_ms']:.2f} ms.",
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the measurement and write batch.json and batch.md."""
    from ..benchmarking import device_slug
    from .job import load_job

    ap = argparse.ArgumentParser(description=(__doc__ or "").strip().splitlines()[0])
    ap.add_argument("--scene", type=Path, help="scene file (default: the built-in demo scene)")
    ap.add_argument("--size", type=int, default=256, help="frame width and height in pixels")
    ap.add_argument("--frames", type=int, default=48, help="frames of the turntable")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="local worker counts to run")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each configuration (medians are reported)")
    ap.add_argument("--ray", action="store_true", help="also measure a Ray actor call's round trip (needs ray)")
    ap.add_argument("--out", type=Path, help="results folder (default: benchmarks/results/<device>/batch/)")
    args = ap.parse_args(argv)
    argv = sys.argv[1:] if argv is None else argv
    load_before = os.getloadavg()[0]  # other work on the machine (CPU figures share its cores)
    from importlib import resources

    with resources.as_file(resources.files("guaca_py.data").joinpath("demo_scene.yaml")) as demo:
        scene = (args.scene or demo).resolve()
        job = load_job(
            {
                "scene": str(scene),
                "frames": args.frames,
                "camera": {"orbit": {}},
                "resolution": [args.size, args.size],
            }
        )
        print(f"plain loop: {scene.name}, {args.size}², {args.frames} frames, {args.repeat} time(s)", flush=True)
        plains: list[dict] = []
        batches: dict[int, list[dict]] = {w: [] for w in args.workers}
        for rep in range(args.repeat):  # interleaved, so a slow spell of the machine hits every configuration
            p = plain_loop(args.scene, job, args.size, check=rep == 0)
            plains.append(p)
            print(f"  plain loop: {p['steady_fps']:.2f} frames/s, first frame {p['first_frame_s']:.2f} s", flush=True)
            for w in args.workers:
                b = batch_run(job, w, plains[0]["digests"], plains[0]["reference"])
                batches[w].append(b)
                print(
                    f"  batch, {w} worker(s): {b['steady_fps']:.2f} frames/s steady, {b['fps']:.2f} whole call, "
                    f"first frame {b['first_frame_s']:.2f} s, images "
                    + ("identical" if b["identical"] else f"differ by at most {b['max_diff']}/255"),
                    flush=True,
                )
    plain = _medians(plains)
    runs = [_medians(batches[w]) for w in args.workers]
    bound = max(1, plains[0]["run_to_run_max_diff"] or 0) if plain["timer"] == "gpu" else 0
    for w, r in zip(args.workers, runs):
        r["identical"] = all(b["identical"] for b in batches[w])
        r["max_diff"] = max((b["max_diff"] or 0) for b in batches[w])
        r["matches"] = r["max_diff"] <= bound
    rec = {
        "command": f"python -m guaca_py.batch.bench {shlex.join(argv)}".rstrip(),
        "scene": scene.stem,
        "size": args.size,
        "frames": args.frames,
        "cpus": os.cpu_count(),
        "load_before": load_before,
        "repeat": args.repeat,
        "plain": {k: v for k, v in plain.items() if k not in ("digests", "reference")},
        "batch": runs,
    }
    if args.ray:
        rec["ray"] = ray_overhead()
    out = (
        args.out
        or Path(__file__).resolve().parents[2] / "benchmarks" / "results" / device_slug(plain["device"]) / "batch"
    )
    out.mkdir(parents=True, exist_ok=True)
    (out / "batch.json").write_text(json.dumps({"device": plain["device"], **rec}, indent=1))
    (out / "batch.md").write_text(markdown(rec))
    print(f"written: {out / 'batch.md'}, {out / 'batch.json'}")
    return 0 if all(b["matches"] for b in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
