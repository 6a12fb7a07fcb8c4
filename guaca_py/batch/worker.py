"""A batch worker: one headless context, a Renderer per variant kept warm, each scene loaded once, PNG encoding beside it.

The same `FrameWorker` serves a local worker process (`process_main`, frames streamed back one by
one through the process's own pipe) and a Ray actor (guaca_py/batch/ray_backend.py, a chunk's
frames returned together). Rendering stays on one thread; PNG encoding (zlib, which releases the
GIL) runs on a small thread pool so the next frame renders while the last one is compressed.
"""

from __future__ import annotations

import io
import os
import socket
import threading
import traceback
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

from .plan import ScenePayload, Task, apply_task


def worker_name() -> str:
    """`host:pid` of this process (the manifest's `worker`)."""
    return f"{socket.gethostname()}:{os.getpid()}"


def encode_png(image, level: int = 6) -> bytes:
    """PNG bytes of an (H, W, 3) uint8 image at zlib `level` (6, Pillow's default, is what `FrameResult.save` writes)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG", compress_level=level)
    return buf.getvalue()


def default_encoders(workers: int) -> int:
    """Encoder threads per worker: the machine's cores shared out, two left to the renderer and the driver, 1 to 16."""
    return max(1, min(16, (os.cpu_count() or 2) // max(1, workers) - 2))


@dataclass(frozen=True)
class WorkerSetup:
    """What every worker of a job gets once: the scenes, the variants, how to write PNGs."""

    scenes: list[ScenePayload]
    variants: dict  # name -> (PipelineConfig, method, transparency overrides)
    png_level: int = 1
    encoders: int | None = None  # threads; None: default_encoders(1) on the worker's machine


class FrameWorker:
    """Renders tasks: a context on GPU `gpu` (EGL device index; None: the default device), a Renderer per variant."""

    def __init__(self, setup: WorkerSetup, gpu: int | None = None):
        self.payloads = {p.name: p for p in setup.scenes}
        self.variants = setup.variants
        self.png_level = setup.png_level
        self.gpu = gpu
        self.scenes: dict = {}
        self.renderers: dict = {}
        self.name = worker_name()
        self.ctx = self._context()
        encoders = setup.encoders or default_encoders(1)
        self.pool = ThreadPoolExecutor(encoders, thread_name_prefix="png")
        # frames read back but not yet encoded: bounded, so rendering never runs far ahead of the encoders
        self.in_flight = threading.BoundedSemaphore(2 * encoders + 1)

    def _context(self):
        from ..context import create_context
        from ..errors import DeviceError

        if not self.gpu:  # device 0 is the one a Renderer of its own would pick
            return create_context()[0]
        import moderngl

        try:
            return moderngl.create_context(standalone=True, backend="egl", require=450, device_index=self.gpu)
        except Exception as exc:
            raise DeviceError(f"could not create an OpenGL 4.5 context on EGL device {self.gpu}: {exc}") from exc

    def renderer(self, variant: str):
        """The variant's Renderer, made on first use on this worker's context and kept."""
        if variant not in self.renderers:
            from ..renderer import Renderer

            pipeline, method, overrides = self.variants[variant]
            self.renderers[variant] = Renderer(
                pipeline, self.ctx, method=method, method_overrides=overrides or None, restore_host_state=False
            )
        return self.renderers[variant]

    def scene(self, name: str):
        """The scene, unpickled on first use and kept (meshes stay on the GPU between frames)."""
        if name not in self.scenes:
            self.scenes[name] = self.payloads[name].load()
        return self.scenes[name]

    def render(self, task: Task) -> tuple:
        """Render one task: (image, record of its stats)."""
        scene = self.scene(task.scene)
        apply_task(scene, task)
        frame = self.renderer(task.variant).render(scene, *task.size)
        s = frame.stats
        record = {
            "passes_ms": {name: p["ms"] for name, p in s["passes"].items()},
            "timer": s.get("timer"),
            "fragments_stored": s.get("fragments", {}).get("stored", 0),
            "frame_wall_ms": s.get("frame_wall_ms"),
            "worker": self.name,
        }
        if s.get("warnings"):
            record["warnings"] = list(s["warnings"])
        return frame.image, record

    def render_chunk(self, tasks: list[Task], emit: Callable[[int, bytes, dict], None] | None = None) -> list[Future]:
        """Render `tasks` in order; each frame's PNG is encoded on the pool and then given to `emit(id, png, record)`.

        Returns the encoding futures (each gives (id, png, record)); rendering of the next frame
        starts as soon as the last one is read back.
        """
        futures = []
        for task in tasks:
            image, record = self.render(task)
            self.in_flight.acquire()
            futures.append(self.pool.submit(self._encode, task.id, image, record, emit))
        return futures

    def _encode(self, task_id: int, image, record: dict, emit) -> tuple[int, bytes, dict]:
        try:
            png = encode_png(image, self.png_level)
            if emit is not None:
                emit(task_id, png, record)
            return task_id, png, record
        finally:
            self.in_flight.release()

    def close(self) -> None:
        """Finish the encodes, free the renderers and the context."""
        self.pool.shutdown(wait=True)
        for r in self.renderers.values():
            r.release()
        self.renderers.clear()
        self.ctx.release()


def process_main(tasks_in, results_out, setup: WorkerSetup, gpu: int | None) -> None:
    """A local worker process: chunks arrive on `tasks_in` (None ends), results leave on `results_out`.

    Messages out: ("ready", name), ("frame", id, png, record), ("error", text). Each
    process has its own pipes, so a worker killed mid-message corrupts only its own (the driver
    reads EOF there and hands its frames to the others).
    """
    lock = threading.Lock()
    failures: list[BaseException] = []  # of encoder threads, raised on the rendering thread

    def send(message) -> None:
        with lock:
            results_out.send(message)

    def emit(task_id: int, png: bytes, record: dict) -> None:
        send(("frame", task_id, png, record))

    def check(future: Future) -> None:
        if future.exception() is not None:
            failures.append(future.exception())

    worker = None
    try:
        worker = FrameWorker(setup, gpu)
        send(("ready", worker.name))
        while not failures:
            chunk = tasks_in.recv()
            if chunk is None:
                break
            for f in worker.render_chunk(chunk, emit):
                f.add_done_callback(check)
        worker.close()
        worker = None
        if failures:
            raise failures[0]
    except EOFError:  # the driver is gone: nothing to report to
        pass
    except BaseException as exc:  # the driver ends the job with this message
        try:
            send(("error", _describe(exc)))
        except OSError:
            pass
    finally:
        if worker is not None:
            worker.pool.shutdown(wait=False, cancel_futures=True)


def _describe(exc: BaseException) -> str:
    """An error as the driver reports it: guaca's own errors by their message, anything else with its traceback."""
    from ..errors import GuacaError

    if isinstance(exc, GuacaError):
        return str(exc)
    return "".join(traceback.format_exception(exc)).rstrip()
