"""The same job on a local Ray instance (2 CPUs): the same images as the plain loop; and a video per variant."""

from __future__ import annotations

import json

import pytest
from batch_jobs import differing, orbit_cameras, sequential_images, write_job

from guaca_py.batch import render_job


def test_ray_renders_the_turntable_like_the_plain_loop(tmp_path):
    ray = pytest.importorskip("ray", reason='Ray is not installed (pip install ".[cluster]")')
    job = write_job(tmp_path, frames=12)
    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING")
    try:
        result = render_job(job, tmp_path / "out", ray=True, progress=False)
        assert result.backend == "ray" and result.rendered == 12
        assert len(result.workers) == 2  # one CPU actor per CPU of the cluster
    finally:
        ray.shutdown()
    lines = [json.loads(t) for t in (tmp_path / "out" / "manifest.jsonl").read_text().splitlines()]
    assert [line["frame"] for line in lines] == list(range(12))
    expected = sequential_images(tmp_path / "scene.yaml", orbit_cameras(12))
    assert differing([tmp_path / "out" / "exact" / f"{i:05d}.png" for i in range(12)], expected) == []


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
