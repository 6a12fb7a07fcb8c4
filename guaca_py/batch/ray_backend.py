"""Ray workers: one actor per GPU of the cluster (`num_gpus=1`), or CPU actors where the cluster has no GPU.

The scenes go into Ray's object store once (`ray.put`) and every actor reads them from there,
so no node needs the job's files. Each actor holds a `FrameWorker` (a Renderer per variant,
scenes loaded once); a chunk comes back as one list of (id, png, record). Events for the driver
are those of guaca_py/batch/local.py: an actor that dies (killed, its node lost) is reported
dead and its chunks go to the others.
"""

from __future__ import annotations

import queue
import threading
import time
from concurrent.futures import Future

from ..errors import GuacaError
from .plan import Task
from .worker import FrameWorker, WorkerSetup


class RayWorker:
    """The actor: a FrameWorker on the GPU Ray assigned (its id taken as the EGL device index).

    The actor takes two calls at once (`max_concurrency`), so the next chunk renders while the
    last one's PNGs are still encoding; every frame is rendered on one thread of its own, which
    made the GL context and keeps it current.
    """

    def __init__(self, setup: WorkerSetup):
        import ray

        ids = ray.get_gpu_ids()
        gpu = int(ids[0]) if ids else None
        self.chunks: queue.Queue = queue.Queue()
        started: Future = Future()
        threading.Thread(target=self._render_loop, args=(setup, gpu, started), daemon=True).start()
        self.worker = started.result()  # an error making the context or a renderer fails the actor here

    def _render_loop(self, setup: WorkerSetup, gpu: int | None, started: Future) -> None:
        try:
            worker = FrameWorker(setup, gpu)
        except BaseException as exc:
            started.set_exception(exc)
            return
        started.set_result(worker)
        while True:
            chunk, rendered = self.chunks.get()
            try:
                rendered.set_result(worker.render_chunk(chunk))
            except BaseException as exc:
                rendered.set_exception(exc)

    def name(self) -> str:
        """`host:pid` of the actor's process."""
        return self.worker.name

    def render(self, chunk: list[Task]) -> list[tuple[int, bytes, dict]]:
        """Render a chunk on the render thread; its frames' (id, png, record) once encoded."""
        rendered: Future = Future()
        self.chunks.put((chunk, rendered))
        return [f.result() for f in rendered.result()]


def import_ray():
    """The ray module, or a GuacaError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise GuacaError('Ray is not installed: pip install "guaca_py[cluster]"') from None
    return ray


class RayWorkers:
    """Actors on a Ray cluster: connects (or starts a local instance) unless Ray is initialised already."""

    kind = "ray"

    def __init__(self, setup: WorkerSetup, address):
        ray = self.ray = import_ray()
        self.owns = not ray.is_initialized()
        if self.owns:
            ray.init(address=None if address is True else address, logging_level="WARNING")
        resources = ray.cluster_resources()
        gpus = int(resources.get("GPU", 0))
        # two calls at once: a chunk renders while the one before it is encoded (RayWorker)
        self.options = {"num_gpus": 1} if gpus else {"num_cpus": 1}
        self.options["max_concurrency"] = 2
        self.count = gpus or max(1, int(resources.get("CPU", 1)))  # workers unless told: one per GPU, else per CPU
        self.actor_class = ray.remote(RayWorker)
        # the scenes go into the object store once; every actor reads them from there
        self.args = (ray.put(setup),)
        self.actors: dict[int, object] = {}
        self.ready: dict[int, str] = {}
        self.inflight: dict = {}  # object ref -> (wid, what): "ready" or the chunk's task ids
        self._next = 0
        self.errors = (ray.exceptions.RayActorError, ray.exceptions.ObjectLostError)

    def start(self, count: int) -> None:
        """Start `count` actors."""
        for _ in range(count):
            self._start()

    def _start(self) -> int:
        wid = self._next
        self._next += 1
        actor = self.actor_class.options(**self.options).remote(*self.args)
        self.actors[wid] = actor
        self.inflight[actor.name.remote()] = (wid, "ready")
        return wid

    def submit(self, wid: int, chunk: list[Task]) -> bool:
        """Queue a chunk on an actor."""
        self.inflight[self.actors[wid].render.remote(chunk)] = (wid, [t.id for t in chunk])
        return True

    def poll(self, timeout: float) -> list[tuple]:
        """Events of the actors within `timeout` seconds."""
        ray = self.ray
        if not self.inflight:
            time.sleep(timeout)
            return []
        refs = list(self.inflight)
        ready, _ = ray.wait(refs, num_returns=1, timeout=timeout)
        if ready:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
        events = []
        for ref in ready:
            if ref not in self.inflight:  # a call of an actor found dead earlier in this loop
                continue
            wid, what = self.inflight.pop(ref)
            try:
                value = ray.get(ref)
            except self.errors as exc:
                if wid in self.actors:
                    events.append(("dead", wid, str(exc).strip() or type(exc).__name__))
                    self._forget(wid)
                continue
            except ray.exceptions.RayTaskError as exc:
                cause = getattr(exc, "cause", None)
                events.append(("error", wid, str(cause) if isinstance(cause, GuacaError) else str(exc)))
                continue
            if what == "ready":
                self.ready[wid] = value
                events.append(("ready", wid, value))
            else:
                events.extend(("frame", wid, *result) for result in value)
        return events

    def _forget(self, wid: int) -> None:
        self.actors.pop(wid, None)
        self.ready.pop(wid, None)
        for ref, (w, _) in list(self.inflight.items()):
            if w == wid:
                del self.inflight[ref]

    def replace(self, wid: int) -> int:
        """Start an actor in place of a dead one (it takes chunks once it answers)."""
        return self._start()

    def pid(self, wid: int) -> int | None:
        """The process id of an actor (from its `host:pid` name)."""
        name = self.ready.get(wid)
        return None if name is None else int(name.rsplit(":", 1)[1])

    def stop(self, wid: int) -> None:
        """End an actor."""
        actor = self.actors.pop(wid, None)
        self.ready.pop(wid, None)
        if actor is not None:
            self.ray.kill(actor)

    def close(self, abort: bool = False) -> None:
        """End every actor; shut Ray down if this job started it."""
        for wid in list(self.actors):
            self.stop(wid)
        self.inflight.clear()
        if self.owns:
            self.ray.shutdown()
