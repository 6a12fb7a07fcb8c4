"""The output folder: one job at a time (stale locks taken over), manifest lines a rerun can trust."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import pytest

from guaca_py.batch.plan import Task
from guaca_py.batch.run import chunks, manifest_line
from guaca_py.batch.store import LOCK, FolderLock, Manifest, write_image
from guaca_py.errors import ConfigError


def _task(i: int, key: str = "k") -> Task:
    return Task(i, "s", "v", i, {}, {}, (4, 4), f"v/{i:05d}.png", key)


def test_a_second_job_on_the_same_folder_is_refused(tmp_path):
    first = FolderLock(tmp_path)
    first.acquire()
    with pytest.raises(ConfigError, match=rf"another batch job is writing to {tmp_path} \(pid {os.getpid()} on "):
        FolderLock(tmp_path).acquire()
    first.release()
    assert not (tmp_path / LOCK).exists()
    second = FolderLock(tmp_path)
    second.acquire()  # free again
    second.release()


def test_a_lock_of_a_dead_job_is_taken_over(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)  # exited: its pid names no process (or, reused, one started later)
    (tmp_path / LOCK).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "proc_start": "1"}))
    lock = FolderLock(tmp_path)
    lock.acquire()
    assert json.loads((tmp_path / LOCK).read_text())["pid"] == os.getpid()
    lock.release()


def test_a_live_process_that_reused_the_pid_does_not_hold_the_lock(tmp_path):
    # this process is alive, but started at another time than the lock's holder did
    (tmp_path / LOCK).write_text(json.dumps({"pid": os.getpid(), "host": socket.gethostname(), "proc_start": "-1"}))
    lock = FolderLock(tmp_path)
    lock.acquire()
    lock.release()


def test_a_lock_from_another_host_is_refused_with_the_file_to_delete(tmp_path):
    (tmp_path / LOCK).write_text(json.dumps({"pid": 1, "host": "render-node-7", "since": "yesterday"}))
    with pytest.raises(ConfigError) as err:
        FolderLock(tmp_path).acquire()
    assert "pid 1 on render-node-7 since yesterday" in str(err.value)
    assert f"delete {tmp_path / LOCK}" in str(err.value)


def test_manifest_keeps_only_checked_frames(tmp_path):
    m = Manifest(tmp_path)
    tasks = [_task(i) for i in range(4)]
    for t in tasks:
        m.append(manifest_line(t, {"worker": "w"}, *write_image(tmp_path, t, b"png %d" % t.id)))
    m.close()
    assert set(m.verified(tasks)) == {0, 1, 2, 3}
    (tmp_path / tasks[1].file).write_bytes(b"png X")  # same size, other bytes
    (tmp_path / tasks[2].file).unlink()
    with open(m.path, "a") as f:
        f.write('{"file": "v/00003.png", "by')  # a driver killed mid-line
    changed = [tasks[0], tasks[1], tasks[2], _task(3, key="other")]  # frame 3 is now another task
    assert set(m.verified(changed)) == {0}
    kept = [m.verified(changed)[0]]
    before = m.path.stat().st_mtime_ns
    m.keep(kept)
    assert [line["file"] for line in m.lines()] == ["v/00000.png"]
    after = m.path.stat().st_mtime_ns
    m.keep(kept)  # nothing to change: not rewritten
    assert m.path.stat().st_mtime_ns == after and after >= before


def test_chunks_stay_within_one_scene_and_variant():
    tasks = [Task(i, "s", "a" if i < 5 else "b", i, {}, {}, (1, 1), "", "") for i in range(9)]
    assert [[t.id for t in c] for c in chunks(tasks, 3)] == [[0, 1, 2], [3, 4], [5, 6, 7], [8]]


def test_progress_counts_done_over_total_with_rate_and_eta():
    from guaca_py.batch.progress import Progress

    now = [100.0]
    p = Progress(10, skipped=4, show=False, clock=lambda: now[0])
    assert p.eta() is None and p.line().endswith("ETA ?")
    p.step()
    p.step()
    now[0] += 4.0  # 2 frames rendered in 4 s: 0.5 frames/s
    line = p.line()
    assert line.startswith("frames 6/10, 0.50 frames/s, ETA ")
    assert p.fps == pytest.approx(0.5) and p.eta() == pytest.approx(8.0)  # the 4 left at the rate of the 2 rendered
