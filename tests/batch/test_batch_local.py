"""`guaca batch` on local worker processes: every frame, byte-identical to a plain loop; killed workers; reruns."""

from __future__ import annotations

import json
import os
import signal

import pytest
from batch_jobs import SCENE, differing, orbit_cameras, sequential_images, write_job

from guaca_py.batch import BatchError, render_job
from guaca_py.batch.store import LOCK, FolderLock
from guaca_py.cli import main


def _files(out) -> dict:
    """Every file under `out` (but the lock) with its bytes and its inode and mtime (a rewrite changes them)."""
    return {
        p.relative_to(out).as_posix(): (p.read_bytes(), p.stat().st_ino, p.stat().st_mtime_ns)
        for p in sorted(out.rglob("*"))
        if p.is_file() and p.name != LOCK
    }


def test_turntable_of_48_frames_on_2_workers_equals_the_plain_loop(tmp_path, capsys):
    job = write_job(tmp_path, frames=48)
    out = tmp_path / "out"
    assert main(["batch", str(job), "--out", str(out), "--workers", "2", "--no-progress"]) == 0
    assert "48 frames rendered, 0 already there, of 48" in capsys.readouterr().out
    lines = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(line["frame"] for line in lines) == list(range(48))  # one line per frame
    assert {line["variant"] for line in lines} == {"exact"}
    # every frame names a worker process of the job (host:pid, never the driver's pid), at most the two
    # asked for; both take chunks unless one started so late (a loaded machine) that the other took all
    workers = {line["worker"] for line in lines}
    assert workers and len(workers) <= 2 and str(os.getpid()) not in {w.rsplit(":", 1)[1] for w in workers}
    for line in lines:
        assert set(line["passes_ms"]) >= {"geometry", "light_culling", "composite"}
        assert line["fragments_stored"] >= 0 and line["file"] == f"exact/{line['frame']:05d}.png"
    assert lines[0]["fragments_stored"] > 0  # from the front; from behind the opaque wall hides the panes
    expected = sequential_images(tmp_path / "scene.yaml", orbit_cameras(48))
    assert differing([out / "exact" / f"{i:05d}.png" for i in range(48)], expected) == []  # byte for byte
    # a rerun through the command reads its own manifest and images back: they are no inputs to protect
    assert main(["batch", str(job), "--out", str(out), "--workers", "2", "--no-progress"]) == 0
    assert "0 frames rendered, 48 already there, of 48" in capsys.readouterr().out


def test_a_killed_worker_loses_no_frame_and_a_rerun_writes_nothing(tmp_path):
    # frames large enough that the job is still running when its first frame is written (llvmpipe)
    job = write_job(tmp_path, frames=24, size=(320, 240))
    out = tmp_path / "out"
    killed: list[int] = []

    def kill_first_worker(line: dict) -> None:
        if not killed:
            killed.append(int(line["worker"].rsplit(":", 1)[1]))
            os.kill(killed[0], signal.SIGKILL)

    result = render_job(job, out, workers=2, chunk=3, progress=False, on_frame=kill_first_worker)
    assert result.rendered == 24 and result.lost > 0
    lines = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
    assert sorted(line["frame"] for line in lines) == list(range(24))
    others = [line for line in lines if not line["worker"].endswith(f":{killed[0]}")]
    assert len(others) >= result.lost  # the frames it lost were rendered by the others
    expected = sequential_images(tmp_path / "scene.yaml", orbit_cameras(24), size=(320, 240))
    assert differing([out / "exact" / f"{i:05d}.png" for i in range(24)], expected) == []

    before = _files(out)
    again = render_job(job, out, workers=2, progress=False)
    assert (again.rendered, again.skipped) == (0, 24)
    assert _files(out) == before  # not one file written again


def test_variants_animation_and_a_damaged_frame(tmp_path):
    variants = "  - {name: exact, pipeline: exact}\n  - {name: fast, set: {threshold: 0.95}}"
    job = write_job(tmp_path, frames=4, variants=variants)
    job.write_text(
        job.read_text()
        + "animate:\n  - node: box\n    keyframes:\n      - {frame: 0}\n      - {frame: 3, rotation_deg: [0, 90, 0]}\n"
        + "png_level: 6\n"  # Pillow's default: the very files FrameResult.save writes
    )
    out = tmp_path / "out"
    result = render_job(job, out, workers=1, progress=False)
    assert result.rendered == 8 and len(result.workers) == 1
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*.png")) == [
        f"{v}/{i:05d}.png" for v in ("exact", "fast") for i in range(4)
    ]

    from guaca_py import Renderer
    from guaca_py.scene.loader import load_scene

    scene = load_scene(tmp_path / "scene.yaml")
    box = scene.nodes[2]
    r = Renderer("default", method_overrides={"threshold": 0.95})
    try:
        for i, cam in enumerate(orbit_cameras(4)):
            scene.camera = cam
            box.transform.rotation_deg = (0.0, -30.0 + (90.0 - -30.0) * (i / 3), 0.0)  # from its own -30 to 90
            ref = r.render(scene, 64, 48).save(tmp_path / "ref.png").read_bytes()
            assert (out / "fast" / f"{i:05d}.png").read_bytes() == ref, i
    finally:
        r.release()

    (out / "fast" / "00002.png").write_bytes(b"not a png")
    before = _files(out)
    again = render_job(job, out, workers=1, progress=False)
    assert (again.rendered, again.skipped) == (1, 7)
    changed = {k for k in before if _files(out)[k] != before[k]}
    assert changed == {"fast/00002.png", "manifest.jsonl"}


def test_a_worker_error_ends_the_job_with_its_message(tmp_path, capsys):
    scene = tmp_path / "bad.yaml"
    scene.write_text(SCENE.replace("description: unlit", "description: no_such_material"))
    job = tmp_path / "job.yaml"
    job.write_text("scene: bad.yaml\nframes: 4\nresolution: [16, 16]\n")
    with pytest.raises(BatchError, match=r"bad.yaml:\d+.*no_such_material"):
        render_job(job, tmp_path / "out", workers=1, progress=False)
    assert not (tmp_path / "out" / LOCK).exists()  # released

    lock = FolderLock(tmp_path / "busy")
    lock.acquire()
    try:
        assert main(["batch", str(job), "--out", str(tmp_path / "busy"), "--no-progress"]) == 2
        assert f"another batch job is writing to {tmp_path / 'busy'}" in capsys.readouterr().err
    finally:
        lock.release()
