"""The output folder of a job: its lock, its manifest, its images and videos, each written atomically.

Only the driver writes here: workers send PNG bytes back (no shared disk needed). An image is
written through a temporary file and a rename (guaca_py/output.py), then its manifest line is
appended with one write; a rerun keeps a frame only when its line names the same task (a digest
of scene, variant, camera, node transforms and size) and the file is there with the recorded
size and SHA-256, so an interrupted job, a torn last line or a damaged file costs only those
frames again.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import time
from pathlib import Path

from ..errors import ConfigError
from ..output import write_atomic
from .plan import Task

MANIFEST = "manifest.jsonl"
LOCK = ".batch.lock"


def _start_time(pid: int) -> str | None:
    """The process's start time in clock ticks since boot (/proc), to tell a live holder from a reused pid."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[-1].split()[19]  # field 22; the name in brackets may hold spaces


def _alive(pid: int, started: str | None) -> bool:
    """Whether process `pid` is the one that took the lock (same start time where /proc tells)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    now = _start_time(pid)
    return started is None or now is None or now == started


class FolderLock:
    """DIR/.batch.lock: pid, host and start time of the job writing DIR; a second job is refused.

    A lock left by a job that died on this host (its pid gone, or taken by another process) is
    stale and taken over; one from another host is refused with the file to delete.
    """

    def __init__(self, out: Path):
        self.path = Path(out) / LOCK
        self.mine: str | None = None

    def acquire(self) -> None:
        """Take the lock or raise ConfigError naming the job that holds it."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        me = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "proc_start": _start_time(os.getpid()),
            "since": time.strftime("%Y-%m-%d %H:%M:%S"),
        }
        text = json.dumps(me)
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                if self._break_stale():
                    continue
                raise self._held() from None
            with os.fdopen(fd, "w") as f:
                f.write(text)
            self.mine = text
            return
        raise self._held()

    def _holder(self) -> dict | None:
        try:
            return json.loads(self.path.read_text())
        except (OSError, ValueError):
            return None

    def _break_stale(self) -> bool:
        """Remove the lock if its job is gone (renamed first, so two jobs never both take it over)."""
        holder = self._holder()
        if holder is None:  # being written this instant, or garbage: stale once it is old
            try:
                if time.time() - self.path.stat().st_mtime < 10:
                    return False
            except OSError:
                return True
        elif holder.get("host") != socket.gethostname() or _alive(int(holder["pid"]), holder.get("proc_start")):
            return False
        grave = self.path.with_name(f"{LOCK}.stale.{os.getpid()}")
        try:
            os.rename(self.path, grave)
        except FileNotFoundError:
            return True  # another job broke it first
        grave.unlink(missing_ok=True)
        return True

    def _held(self) -> ConfigError:
        h = self._holder() or {}
        who = f"pid {h.get('pid', '?')} on {h.get('host', '?')} since {h.get('since', '?')}"
        return ConfigError(
            f"another batch job is writing to {self.path.parent} ({who})",
            key="--out",
            hint=f"wait for it, or, if that job is gone, delete {self.path}",
        )

    def release(self) -> None:
        """Remove the lock if it is still this job's."""
        if self.mine is not None and self.path.is_file() and self.path.read_text() == self.mine:
            self.path.unlink()
        self.mine = None


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class Manifest:
    """DIR/manifest.jsonl: one JSON line per finished frame and variant."""

    def __init__(self, out: Path):
        self.out = Path(out)
        self.path = self.out / MANIFEST
        self._fd: int | None = None

    def lines(self) -> list[dict]:
        """The parseable lines (a torn last line of a killed job is skipped)."""
        if not self.path.is_file():
            return []
        out = []
        for text in self.path.read_text(errors="replace").splitlines():
            try:
                line = json.loads(text)
            except ValueError:
                continue
            if isinstance(line, dict):
                out.append(line)
        return out

    def verified(self, tasks: list[Task]) -> dict[int, dict]:
        """The lines of `tasks` already done: same task key, the file there with the recorded size and SHA-256."""
        by_file = {t.file: t for t in tasks}
        done: dict[int, dict] = {}
        for line in self.lines():
            task = by_file.get(line.get("file"))
            if task is None or line.get("key") != task.key:
                continue
            path = self.out / task.file
            try:
                if path.stat().st_size != line.get("bytes") or _digest(path.read_bytes()) != line.get("sha256"):
                    continue
            except OSError:
                continue
            done[task.id] = line
        return done

    def keep(self, lines: list[dict]) -> None:
        """Make the manifest hold exactly `lines` (rewritten atomically, and only if that changes it)."""
        text = "".join(json.dumps(line) + "\n" for line in lines)
        current = self.path.read_text(errors="replace") if self.path.is_file() else None
        if current != text and (lines or current is not None):
            write_atomic(self.path, lambda tmp: tmp.write_text(text), "--out")

    def append(self, line: dict) -> None:
        """Add one line with a single write (a killed driver leaves at most a torn last line)."""
        if self._fd is None:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        os.write(self._fd, (json.dumps(line) + "\n").encode())

    def close(self) -> None:
        """Flush the lines to the disk."""
        if self._fd is not None:
            os.fsync(self._fd)
            os.close(self._fd)
            self._fd = None


def write_image(out: Path, task: Task, png: bytes) -> tuple[int, str]:
    """Write a frame's PNG atomically; its size and SHA-256 (for the manifest)."""
    write_atomic(Path(out) / task.file, lambda tmp: tmp.write_bytes(png), "--out")
    return len(png), _digest(png)


def write_video(out: Path, rel: str, tasks: list[Task], fps: float) -> Path:
    """An H.264 MP4 of the tasks' images in frame order, written atomically (imageio-ffmpeg)."""
    import imageio_ffmpeg
    import numpy as np
    from PIL import Image

    size = tasks[0].size

    def write(tmp: Path) -> None:
        # the temporary file has no .mp4 suffix to infer the container from: name it
        frames = imageio_ffmpeg.write_frames(
            str(tmp), size, fps=fps, macro_block_size=1, output_params=["-y", "-f", "mp4"]
        )
        frames.send(None)
        try:
            for t in tasks:
                with Image.open(Path(out) / t.file) as img:
                    frames.send(np.ascontiguousarray(np.asarray(img.convert("RGB"))))
        finally:
            frames.close()

    return write_atomic(Path(out) / rel, write, "--out")
