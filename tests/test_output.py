"""Output files: written all or nothing, with the permissions the user's umask gives new files."""

from __future__ import annotations

import os
import stat

import pytest

from guaca_py.errors import ConfigError
from guaca_py.output import write_atomic


@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_files_follow_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        p = write_atomic(tmp_path / "out.json", lambda tmp: tmp.write_text("{}"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == mode
    assert p.read_text() == "{}" and [q.name for q in tmp_path.iterdir()] == ["out.json"]  # no temporary left


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    p = tmp_path / "out.json"
    p.write_text("old")

    def fail(tmp):
        tmp.write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(ConfigError, match="No space left on device"):
        write_atomic(p, fail)
    assert p.read_text() == "old" and [q.name for q in tmp_path.iterdir()] == ["out.json"]
