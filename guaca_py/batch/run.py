"""`render_job`: the driver of a batch job. It loads the scenes, plans the frames, hands them out, writes what comes back.

Frames are handed out in chunks of consecutive frames of one scene and variant (so a worker
keeps its renderer and scene warm), at most two chunks per worker at a time (one rendering, one
waiting), so a slow worker holds back at most one chunk. A worker that dies (SIGKILL, a crash, a
lost Ray node) gives its unfinished frames back to the queue, and another worker is started in
its place; a frame lost with MAX_ATTEMPTS workers ends the job. An error a worker reports (a
method the device cannot run, a shader that does not compile) ends the job with its message.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError, GuacaError
from ..output import active_reads
from .job import Job, load_job
from .plan import Task, plan, scene_payload, video_groups
from .progress import Progress
from .store import FolderLock, Manifest, write_image, write_video
from .worker import WorkerSetup

MAX_ATTEMPTS = 3  # workers a frame may be lost with before the job gives up on it
IN_FLIGHT_CHUNKS = 2  # chunks a worker holds at once: the one it renders and the next
MAX_CHUNK = 8


class BatchError(GuacaError):
    """A batch job could not finish: a worker reported an error, or frames kept losing their workers."""


@dataclass
class BatchResult:
    """What a job did: frames written and skipped, time, rate, the manifest and videos."""

    out: Path
    total: int
    rendered: int
    skipped: int
    seconds: float
    first_frame_s: float | None  # from the call to the first frame written (None: nothing rendered)
    workers: list[str] = field(default_factory=list)  # host:pid of every worker that reported
    lost: int = 0  # frames re-rendered after their worker died
    videos: list[Path] = field(default_factory=list)
    backend: str = "local"

    @property
    def fps(self) -> float:
        """Frames rendered per second over the whole call."""
        return self.rendered / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> str:
        """One line for the command line."""
        first = "" if self.first_frame_s is None else f"; first frame after {self.first_frame_s:.1f} s"
        lost = f"; {self.lost} frames re-run after a worker died" if self.lost else ""
        return (
            f"{self.rendered} frames rendered, {self.skipped} already there, of {self.total}, in {self.seconds:.1f} s "
            f"({self.fps:.2f} frames/s) on {len(self.workers)} {self.backend} worker(s){first}{lost}"
        )


def chunks(tasks: list[Task], size: int) -> deque[list[Task]]:
    """Runs of at most `size` tasks of one scene and variant, in order."""
    out: deque[list[Task]] = deque()
    for t in tasks:
        last = out[-1] if out else None
        if last and len(last) < size and (last[-1].scene, last[-1].variant) == (t.scene, t.variant):
            last.append(t)
        else:
            out.append([t])
    return out


def auto_chunk(todo: int, workers: int) -> int:
    """Frames per chunk: about four chunks per worker, 1 to MAX_CHUNK."""
    return max(1, min(MAX_CHUNK, math.ceil(todo / (4 * max(1, workers)))))


def render_job(
    job: str | Path | dict | Job,
    out: str | Path,
    *,
    workers: int | None = None,
    ray: bool | str | None = None,
    chunk: int | None = None,
    encoders: int | None = None,
    progress: bool = True,
    on_frame: Callable[[dict], None] | None = None,
) -> BatchResult:
    """Render every frame of `job` into `out` (DIR/<variant>/<frame>.png, DIR/manifest.jsonl); skip frames already there.

    `workers`: local worker processes (default one per GPU, one on a software rasterizer) or
    Ray actors (default one per GPU of the cluster, else per CPU). `ray`: True to run on Ray
    (RAY_ADDRESS or a new local instance; an initialised Ray is used as it is), or a cluster
    address. `chunk`: frames handed out at once (default: about four chunks per worker, at most
    8). `encoders`: PNG encoding threads per worker. `on_frame(line)` is called with each
    manifest line as it is written.
    """
    t0 = time.perf_counter()
    job = job if isinstance(job, Job) else load_job(job)
    for name, value in (("workers", workers), ("chunk", chunk), ("encoders", encoders)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ConfigError(f"must be a whole number >= 1, got {value!r}", key=f"--{name}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("is a file, not a folder", out, key="--out", hint="give a folder for the frames")
    log = active_reads()
    if log is not None:  # the manifest and images a rerun reads back are this job's own, not its inputs
        log.own_folder(out)
    lock = FolderLock(out)
    lock.acquire()
    try:
        return _run(job, out, t0, workers, ray, chunk, encoders, progress, on_frame)
    finally:
        lock.release()


def _run(job: Job, out: Path, t0, workers, ray, chunk, encoders, progress, on_frame) -> BatchResult:
    payloads = [scene_payload(path, name) for path, name in zip(job.scenes, job.scene_names)]
    tasks = plan(job, payloads)
    manifest = Manifest(out)
    done = manifest.verified(tasks)
    manifest.keep([done[t.id] for t in tasks if t.id in done])  # this job's good lines, in its order
    todo = [t for t in tasks if t.id not in done]
    result = BatchResult(out, len(tasks), 0, len(done), 0.0, None, backend="ray" if ray else "local")
    rendered_groups: set[str] = set()
    if todo:
        variants = {v.name: (v.pipeline, v.method, v.overrides) for v in job.variants}
        setup = WorkerSetup(payloads, variants, job.png_level, encoders)
        if ray:
            from .ray_backend import RayWorkers

            backend = RayWorkers(setup, ray)
        else:
            from .local import LocalWorkers

            backend = LocalWorkers(setup)
        count = workers or backend.count
        size = chunk or auto_chunk(len(todo), count)
        pending = chunks(todo, size)
        try:
            backend.start(min(count, len(pending)))
            bar = Progress(len(tasks), len(done), progress)
            done.update(_drive(backend, pending, out, manifest, result, t0, bar, on_frame))
        finally:
            manifest.close()
        manifest.keep([done[t.id] for t in tasks])  # in frame order: a rerun finds it as it is and leaves it
        rendered_groups = {str(Path(t.file).parent) + ".mp4" for t in todo}
    if job.video:
        for rel, group in video_groups(tasks).items():
            if rel in rendered_groups or not (out / rel).is_file():
                result.videos.append(write_video(out, rel, group, job.fps))
    result.seconds = time.perf_counter() - t0
    return result


def manifest_line(task: Task, record: dict, size: int, sha256: str) -> dict:
    """A frame's manifest line: what it is (scene, variant, frame, camera, file), its stats and worker, its checks."""
    nodes = {"nodes": {str(k): v for k, v in task.nodes.items()}} if task.nodes else {}
    where = {"scene": task.scene, "variant": task.variant, "frame": task.frame, "file": task.file}
    checks = {"bytes": size, "sha256": sha256, "key": task.key}
    return {**where, "camera": task.camera, **nodes, "size": list(task.size), **record, **checks}


def _drive(backend, pending: deque, out: Path, manifest: Manifest, result: BatchResult, t0, bar, on_frame) -> dict:
    """Hand out chunks, collect frames, write them and their manifest lines, until every frame is written.

    Returns the manifest lines written, by task id.
    """
    tasks = {t.id: t for c in pending for t in c}
    held: dict[int, list[list[int]]] = {}  # worker -> its chunks' unfinished task ids
    ready: set[int] = set()
    names: dict[int, str] = {}
    attempts: dict[int, int] = {}
    writes: dict[Future, tuple[Task, dict]] = {}
    lines: dict[int, dict] = {}
    remaining = len(tasks)
    received: set[int] = set()
    unready_deaths = 0
    aborted = True
    with ThreadPoolExecutor(4, thread_name_prefix="write") as pool:
        try:
            while remaining:
                for wid in sorted(ready):
                    while pending and len(held.get(wid, ())) < IN_FLIGHT_CHUNKS:
                        c = pending.popleft()
                        held.setdefault(wid, []).append([t.id for t in c])
                        backend.submit(wid, c)
                for event in backend.poll(0.05 if writes else 0.5):
                    kind, wid = event[0], event[1]
                    if kind == "ready":
                        ready.add(wid)
                        names[wid] = event[2]
                        result.workers.append(event[2])
                    elif kind == "frame":
                        task_id, png, record = event[2:]
                        for c in held.get(wid, []):
                            if task_id in c:
                                c.remove(task_id)
                        held[wid] = [c for c in held.get(wid, []) if c]
                        if task_id in received:  # a frame can arrive twice only from a worker declared dead
                            continue
                        received.add(task_id)
                        task = tasks[task_id]
                        writes[pool.submit(write_image, out, task, png)] = (task, record)
                    elif kind == "error":
                        raise BatchError(f"worker {names.get(wid, wid)}: {event[2]}")
                    elif kind == "dead":
                        why = event[2] if len(event) > 2 else "it exited"
                        if wid not in ready:
                            unready_deaths += 1
                            if unready_deaths >= MAX_ATTEMPTS:
                                raise BatchError(f"{unready_deaths} workers died before they started (last: {why})")
                        ready.discard(wid)
                        lost = [i for c in held.pop(wid, []) for i in c if i not in received]
                        for i in lost:
                            attempts[i] = attempts.get(i, 0) + 1
                            if attempts[i] >= MAX_ATTEMPTS:
                                t = tasks[i]
                                raise BatchError(
                                    f"frame {t.frame} of variant '{t.variant}' (scene '{t.scene}') lost its worker "
                                    f"{attempts[i]} times (last: {why})"
                                )
                        if lost:
                            result.lost += len(lost)
                            pending.extendleft(reversed(list(chunks([tasks[i] for i in lost], MAX_CHUNK))))
                        if pending:
                            backend.replace(wid)
                for f in [f for f in writes if f.done()]:
                    task, record = writes.pop(f)
                    line = manifest_line(task, record, *f.result())
                    manifest.append(line)
                    lines[task.id] = line
                    remaining -= 1
                    result.rendered += 1
                    if result.first_frame_s is None:
                        result.first_frame_s = time.perf_counter() - t0
                    bar.step()
                    if on_frame is not None:
                        on_frame(line)
            aborted = False
            return lines
        finally:
            backend.close(abort=aborted)
            for f in list(writes):  # frames already received are kept, even when the job ends early
                task, record = writes.pop(f)
                if f.exception() is None:
                    manifest.append(manifest_line(task, record, *f.result()))
            bar.close()
