"""Local workers: processes started with `spawn`, each with a pipe in and a pipe out of its own.

Events for the driver (guaca_py/batch/run.py): ("ready", wid, name), ("frame", wid, id, png,
record), ("error", wid, text), ("dead", wid). A worker that exits without being told to (killed,
crashed) is reported dead once its pipe is drained; the frames it had not sent go to the others.
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import shutil
import subprocess
from multiprocessing.connection import wait

from .plan import Task
from .worker import WorkerSetup, default_encoders, process_main


def gpu_count() -> int:
    """NVIDIA GPUs on this machine (nvidia-smi -L), 0 where there is none or no driver."""
    exe = shutil.which("nvidia-smi")
    if exe is None:
        return 0
    try:
        out = subprocess.run([exe, "-L"], capture_output=True, text=True, timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return 0
    return sum(1 for line in out.splitlines() if line.startswith("GPU "))


class _Proc:
    def __init__(self, process, tasks, results):
        self.process, self.tasks, self.results = process, tasks, results
        self.stopping = False


class LocalWorkers:
    """Worker processes on this machine: one per GPU (round robin when more are asked), else on the default device."""

    kind = "local"

    def __init__(self, setup: WorkerSetup):
        self.ctx = mp.get_context("spawn")  # no fork: a forked GL or EGL state is not safe to use
        self.setup = setup
        self.gpus = gpu_count()
        self.count = max(1, self.gpus)  # workers unless told: one per GPU, one on a software rasterizer
        self.procs: dict[int, _Proc] = {}
        self._next = 0

    def start(self, count: int) -> None:
        """Start `count` worker processes."""
        if self.setup.encoders is None:  # this machine's cores shared by its workers
            self.setup = dataclasses.replace(self.setup, encoders=default_encoders(count))
        for _ in range(count):
            self._start()

    def _start(self) -> int:
        wid = self._next
        self._next += 1
        tasks_in, tasks_out = self.ctx.Pipe(duplex=False)  # the child receives chunks, the driver sends
        results_in, results_out = self.ctx.Pipe(duplex=False)  # the driver receives frames, the child sends
        gpu = wid % self.gpus if self.gpus else None
        p = self.ctx.Process(
            target=process_main,
            args=(tasks_in, results_out, self.setup, gpu),
            name=f"guaca-batch-{wid}",
            daemon=True,
        )
        p.start()
        tasks_in.close()  # the child holds these ends; closing ours lets EOF tell us it died
        results_out.close()
        self.procs[wid] = _Proc(p, tasks_out, results_in)
        return wid

    def submit(self, wid: int, chunk: list[Task]) -> bool:
        """Send a chunk; False when the worker is gone (its death is reported by poll)."""
        try:
            self.procs[wid].tasks.send(chunk)
            return True
        except OSError:
            return False

    def poll(self, timeout: float) -> list[tuple]:
        """Events of the workers within `timeout` seconds."""
        by_conn = {p.results: wid for wid, p in self.procs.items()}
        events = []
        for conn in wait(list(by_conn), timeout):
            wid = by_conn[conn]
            try:
                while conn.poll():
                    message = conn.recv()
                    events.append((message[0], wid, *message[1:]))
            except (EOFError, OSError):  # exited: what it sent is read; the rest of its frames are lost
                events.append(self._gone(wid))
        return events

    def _gone(self, wid: int) -> tuple:
        p = self.procs.pop(wid)
        p.process.join(timeout=5)
        p.results.close()
        p.tasks.close()
        return ("stopped", wid) if p.stopping else ("dead", wid)

    def replace(self, wid: int) -> int:
        """Start a worker in place of a dead one."""
        return self._start()

    def pid(self, wid: int) -> int | None:
        """The process id of a worker."""
        p = self.procs.get(wid)
        return None if p is None else p.process.pid

    def stop(self, wid: int) -> None:
        """Ask a worker to finish its encodes and exit."""
        p = self.procs[wid]
        p.stopping = True
        try:
            p.tasks.send(None)
        except OSError:
            pass

    def close(self, abort: bool = False, timeout: float = 30.0) -> None:
        """Stop every worker; `abort`: at once, else after its encodes (one that does not exit in time is terminated)."""
        for wid in list(self.procs):
            if not self.procs[wid].stopping:
                self.stop(wid)
        for p in self.procs.values():
            p.process.join(0 if abort else timeout)
            if p.process.is_alive():
                p.process.terminate()
                p.process.join(5)
            p.results.close()
            p.tasks.close()
        self.procs.clear()
