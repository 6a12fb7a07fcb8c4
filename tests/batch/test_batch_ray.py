"""The same job on a local Ray instance (2 CPUs): the same images as the plain loop; and a video per variant."""

from __future__ import annotations

import json
import os
import signal

import pytest
from batch_jobs import differing, orbit_cameras, sequential_images, write_job

from guaca_py.batch import render_job
from guaca_py.batch.ray_backend import RayWorkers


@pytest.fixture(scope="module")
def local_ray():
    """A local Ray instance with 2 CPUs for this module's tests."""
    ray = pytest.importorskip("ray", reason='Ray is not installed (pip install ".[cluster]")')
    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    yield ray
    ray.shutdown()


def test_ray_renders_the_turntable_like_the_plain_loop(tmp_path, local_ray, monkeypatch):
    started: list[int] = []
    start = RayWorkers.start
    monkeypatch.setattr(RayWorkers, "start", lambda self, count: (started.append(count), start(self, count))[1])
    job = write_job(tmp_path, frames=12)
    result = render_job(job, tmp_path / "out", ray=True, progress=False)
    assert result.backend == "ray" and result.rendered == 12
    assert started == [2]  # one CPU actor per CPU of the cluster
    lines = [json.loads(t) for t in (tmp_path / "out" / "manifest.jsonl").read_text().splitlines()]
    assert [line["frame"] for line in lines] == list(range(12))
    # every frame names an actor that reported, each reported once (one that started after the other had
    # rendered all 12 frames never reports, so one or both do)
    assert len(set(result.workers)) == len(result.workers)
    assert {line["worker"] for line in lines} <= set(result.workers)
    expected = sequential_images(tmp_path / "scene.yaml", orbit_cameras(12))
    assert differing([tmp_path / "out" / "exact" / f"{i:05d}.png" for i in range(12)], expected) == []


def test_a_killed_actor_loses_no_frame(tmp_path, local_ray):
    job = write_job(tmp_path, frames=16, size=(320, 240))
    killed: list[int] = []

    def kill_first_actor(line: dict) -> None:
        if not killed:
            killed.append(int(line["worker"].rsplit(":", 1)[1]))
            os.kill(killed[0], signal.SIGKILL)

    result = render_job(job, tmp_path / "out", ray=True, chunk=2, progress=False, on_frame=kill_first_actor)
    assert result.rendered == 16 and result.lost > 0
    expected = sequential_images(tmp_path / "scene.yaml", orbit_cameras(16), size=(320, 240))
    assert differing([tmp_path / "out" / "exact" / f"{i:05d}.png" for i in range(16)], expected) == []


def test_video_per_variant(tmp_path):
    ffmpeg = pytest.importorskip("imageio_ffmpeg", reason='imageio-ffmpeg is not installed (pip install ".[video]")')
    job = write_job(tmp_path, frames=6, variants="  - {name: exact, pipeline: exact}\n  - {name: fast}")
    job.write_text(job.read_text() + "video: true\nfps: 12\n")
    result = render_job(job, tmp_path / "out", workers=1, progress=False)
    assert sorted(p.name for p in result.videos) == ["exact.mp4", "fast.mp4"]
    reader = ffmpeg.read_frames(str(tmp_path / "out" / "exact.mp4"))
    meta = next(reader)
    assert meta["size"] == (64, 48) and meta["fps"] == 12
    assert sum(1 for _ in reader) == 6
    before = (tmp_path / "out" / "exact.mp4").stat().st_mtime_ns
    assert render_job(job, tmp_path / "out", workers=1, progress=False).videos == []  # nothing new: kept
    assert (tmp_path / "out" / "exact.mp4").stat().st_mtime_ns == before
