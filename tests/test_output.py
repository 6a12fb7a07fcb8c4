"""Output files: written all or nothing, never over an input, a device, a FIFO or through a dangling link;
with the permissions the user's umask gives new files and the mode of the file they replace."""

from __future__ import annotations

import os
import re
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from guaca_py.errors import ConfigError
from guaca_py.output import (
    IMAGE_SUFFIXES,
    TEMP_PREFIX,
    check_distinct,
    check_writable,
    recording_reads,
    write_atomic,
)

ROOT = Path(__file__).resolve().parents[1]


def text(s: str):
    """A writer that puts `s` in the temporary file."""
    return lambda tmp: tmp.write_text(s)


def names(folder: Path) -> list[str]:
    """What the folder holds, sorted: a temporary file left behind shows here."""
    return sorted(p.name for p in folder.iterdir())


def assert_refused(path, option: str, match: str) -> None:
    """check_writable and write_atomic both refuse `path` under `option`, with `match` in the message."""
    for call in (lambda: check_writable(path, option), lambda: write_atomic(path, text("x"), option)):
        with pytest.raises(ConfigError, match=match) as err:
            call()
        assert option in str(err.value), err.value


@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_files_follow_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        p = write_atomic(tmp_path / "out.json", text("{}"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == mode
    assert p.read_text() == "{}" and names(tmp_path) == ["out.json"]  # no temporary left


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o600, 0o664])
def test_a_replaced_file_keeps_its_mode(tmp_path, mode):
    p = tmp_path / "out.json"
    p.write_text("old")
    p.chmod(mode)
    old = os.umask(0o077)  # would give 0600 to a new file: the replaced one's mode wins
    try:
        write_atomic(p, text("new"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == mode and p.read_text() == "new"


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    p = tmp_path / "out.json"
    p.write_text("old")

    def fail(tmp):
        tmp.write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(ConfigError, match="No space left on device"):
        write_atomic(p, fail)
    assert p.read_text() == "old" and names(tmp_path) == ["out.json"]


def test_the_temporary_name_is_short_and_beside_the_target(tmp_path):
    """A name of 255 bytes (the most ext4 takes) is written: the temporary's name does not grow with it."""
    seen = []
    longest = "a" * 251 + ".png"
    p = write_atomic(tmp_path / longest, lambda tmp: (seen.append(tmp), tmp.write_bytes(b"x")))
    assert p.read_bytes() == b"x" and names(tmp_path) == [longest]
    assert seen[0].parent == tmp_path and seen[0].name.startswith(TEMP_PREFIX) and len(seen[0].name) == 14
    assert check_writable(tmp_path / ("b" * 246 + ".png"), "--out", IMAGE_SUFFIXES).name.startswith("b")


@pytest.mark.parametrize(
    "path,needles",
    [
        ("", ["--out: the path is empty"]),
        ("a\0b.png", ["NUL"]),
        ("somewhere/", ["names a directory"]),
        ("x" * 300 + ".png", ["304 bytes", "at most 255"]),
        ("d/" * 2100 + "o.png", ["the path is 4205 bytes", "at most 4095"]),
    ],
)
def test_paths_the_system_cannot_take_are_refused(tmp_path, monkeypatch, path, needles):
    monkeypatch.chdir(tmp_path)
    for n in needles:
        assert_refused(path, "--out", re.escape(n))
    assert names(tmp_path) == []


def test_fifos_sockets_and_directories_are_refused_and_left_alone(tmp_path):
    """As root too: the check is on the file's type, not on a permission root would bypass."""
    import socket

    fifo = tmp_path / "pipe.png"
    os.mkfifo(fifo)
    sock_path = tmp_path / "s.json"
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(sock_path))
    (tmp_path / "dir.png").mkdir()
    try:
        for p, kind in ((fifo, "FIFO"), (sock_path, "socket"), (tmp_path / "dir.png", "directory")):
            assert_refused(p, "--out", kind)
        assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and stat.S_ISSOCK(os.lstat(sock_path).st_mode)
        assert (tmp_path / "dir.png").is_dir() and names(tmp_path) == ["dir.png", "pipe.png", "s.json"]
    finally:
        sock.close()


def test_a_device_is_refused():
    """/dev/null is only looked at: the refusal comes before anything is opened for writing."""
    before = os.stat(os.devnull)
    assert_refused(os.devnull, "--stats", "character device, not a regular file")
    after = os.stat(os.devnull)
    assert stat.S_ISCHR(after.st_mode) and (after.st_ino, after.st_rdev) == (before.st_ino, before.st_rdev)


def test_a_link_is_written_through_to_a_regular_file_only(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("old")
    target.chmod(0o640)
    link = tmp_path / "link.json"
    link.symlink_to("real.json")
    chain = tmp_path / "chain.json"
    chain.symlink_to("link.json")
    write_atomic(chain, text("new"))
    assert link.is_symlink() and chain.is_symlink() and os.readlink(chain) == "link.json"
    assert target.read_text() == "new" and stat.S_IMODE(target.stat().st_mode) == 0o640
    assert names(tmp_path) == ["chain.json", "link.json", "real.json"]

    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "to_fifo.png").symlink_to("fifo")
    (tmp_path / "to_dir.png").symlink_to(".")
    (tmp_path / "dangling.png").symlink_to("missing.png")
    (tmp_path / "loop_a.png").symlink_to("loop_b.png")
    (tmp_path / "loop_b.png").symlink_to("loop_a.png")
    for name, needle in [
        ("to_fifo.png", "FIFO (named pipe) (through a symbolic link)"),
        ("to_dir.png", "directory (through a symbolic link)"),
        ("dangling.png", "symbolic link to a missing file"),
        ("loop_a.png", "symbolic link to nothing"),
    ]:
        assert_refused(tmp_path / name, "--out", re.escape(needle))
        assert (tmp_path / name).is_symlink()
    assert not (tmp_path / "missing.png").exists() and stat.S_ISFIFO(os.stat(tmp_path / "fifo").st_mode)


def test_a_file_the_run_read_is_never_an_output(tmp_path):
    """Whatever opened it (here plain open()), through another spelling, a hard link or a symbolic link."""
    scene, texture = tmp_path / "scene.yaml", tmp_path / "tex.png"
    scene.write_text("scene")
    texture.write_bytes(b"texture")
    (tmp_path / "hard.png").hardlink_to(texture)
    (tmp_path / "soft.png").symlink_to("tex.png")
    with recording_reads() as log:
        log.label(scene, "the scene file")  # named before it is read: refused under that name
        with pytest.raises(ConfigError, match="'--stats': is the scene file: writing the output would destroy it"):
            check_writable(scene, "--stats")
        texture.read_bytes()
        for spelling in (texture, tmp_path / "." / "tex.png", tmp_path / "hard.png", tmp_path / "soft.png"):
            assert_refused(spelling, "--out", "is an input of this run")
        written = write_atomic(tmp_path / "o.json", text("out"))  # written, not read: may be replaced again
        write_atomic(written, text("again"))
    assert texture.read_bytes() == b"texture" and scene.read_text() == "scene" and written.read_text() == "again"
    write_atomic(texture, text("replaced"))  # outside the recording nothing is protected: the API's caller decides
    assert texture.read_text() == "replaced"


def test_two_outputs_of_one_run_never_name_one_file(tmp_path):
    (tmp_path / "a.png").write_bytes(b"a")
    (tmp_path / "hard.png").hardlink_to(tmp_path / "a.png")
    check_distinct({"--out": tmp_path / "a.png", "--stats": tmp_path / "b.json", "--other": None})
    for other in (tmp_path / "a.png", tmp_path / "sub" / ".." / "a.png", tmp_path / "hard.png"):
        with pytest.raises(ConfigError, match="'--stats': names the same file as --out"):
            check_distinct({"--out": tmp_path / "a.png", "--stats": other})
    with pytest.raises(ConfigError, match="same file"):  # neither exists yet: the resolved paths are compared
        check_distinct({"--out": tmp_path / "new.png", "--stats": tmp_path / "." / "new.png"})


SLOW_WRITE = """
import os, signal, sys, time
from guaca_py.output import write_atomic

# a process started under nohup inherits SIGHUP ignored, which write_atomic rightly leaves alone:
# the cases below are about the default dispositions
signal.signal(signal.SIGHUP, signal.SIG_DFL)

def slow(tmp):
    tmp.write_text("partial")
    os.kill(os.getpid(), getattr(signal, sys.argv[2]))  # the signal arrives in the middle of the write
    time.sleep(30)

if sys.argv[3] == "handler":  # the application's own handler stays in charge
    signal.signal(signal.SIGTERM, lambda *a: sys.exit(7))
write_atomic(sys.argv[1], slow)
"""


@pytest.mark.parametrize(
    "sig,handler,status", [("SIGTERM", "", -15), ("SIGHUP", "", -1), ("SIGINT", "", -2), ("SIGTERM", "handler", 7)]
)
def test_a_signal_during_the_write_leaves_no_temporary(tmp_path, sig, handler, status):
    """The previous file stays; the temporary is removed; the process ends as the signal says (by it, by
    KeyboardInterrupt, or by the application's handler)."""
    out = tmp_path / "out.json"
    out.write_text("old")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH")))))
    r = subprocess.run(
        [sys.executable, "-c", SLOW_WRITE, str(out), sig, handler],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    assert r.returncode == status, r.stderr
    assert out.read_text() == "old" and names(tmp_path) == ["out.json"]
    if sig == "SIGINT":
        assert r.stderr.rstrip().endswith("KeyboardInterrupt")


def test_default_handlers_are_restored_after_a_write(tmp_path):
    before = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)}
    write_atomic(tmp_path / "o.json", text("x"))
    assert {s: signal.getsignal(s) for s in before} == before


def test_the_screenshot_key_never_replaces_a_file(tmp_path, monkeypatch, gl_context):
    """P takes the first free guaca_screenshot_NNN.png: a screenshot of an earlier session stays."""
    from guaca_py.scene.loader import demo_scene
    from guaca_py.viewer.app import Viewer

    monkeypatch.chdir(tmp_path)
    (tmp_path / "guaca_screenshot_000.png").write_bytes(b"earlier")
    viewer = Viewer(gl_context, demo_scene())
    fbo = gl_context.simple_framebuffer((32, 24))
    try:
        viewer.key("P")
        viewer.key("P")
        assert viewer.screenshot_requests == [Path("guaca_screenshot_001.png"), Path("guaca_screenshot_002.png")]
        viewer.frame(fbo, (32, 24))
        assert viewer.screenshots_taken == [
            Path("guaca_screenshot_001.png"),
            Path("guaca_screenshot_002.png"),
        ]
        assert (tmp_path / "guaca_screenshot_000.png").read_bytes() == b"earlier"

        def disk_full(path, write, option="output"):
            raise ConfigError("cannot write: No space left on device", path, key=option)

        monkeypatch.setattr("guaca_py.output.write_atomic", disk_full)
        viewer.key("P")  # a failed key screenshot is a note on screen; the viewer goes on
        viewer.frame(fbo, (32, 24))
        assert any("screenshot not saved" in text and "No space left" in text for text, _ in viewer.notes)
        viewer.screenshot_requests.append(Path("asked.png"))  # one the caller asked for: its failure is raised
        with pytest.raises(ConfigError, match="'screenshot': cannot write: No space left on device"):
            viewer.frame(fbo, (32, 24))
    finally:
        fbo.release()
        viewer.release()
