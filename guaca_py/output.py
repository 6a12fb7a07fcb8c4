"""Output files: checked before a render starts, written atomically so a failure never truncates a good file."""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path

from .errors import ConfigError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm")


def check_writable(path: str | Path, option: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """Fail now, before minutes of rendering, if `path` cannot be written: suffix, directory, permissions."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError("is a directory", p, key=option, hint="give a file name inside it, e.g. DIR/out.png")
    if suffixes is not None and p.suffix.lower() not in suffixes:
        got = f"'{p.suffix}'" if p.suffix else "no extension"
        raise ConfigError(
            f"cannot tell the image format from {got}", p, key=option, hint=f"end the name with {', '.join(suffixes)}"
        )
    parent = p.parent
    for up in (parent, *parent.parents):
        if up.exists():
            if not up.is_dir():
                raise ConfigError(f"{up} is a file, not a directory", p, key=option, hint="choose another path")
            if not os.access(up, os.W_OK | os.X_OK):
                raise ConfigError(f"directory {up} is not writable", p, key=option, hint="choose a writable place")
            break
    if p.exists() and not os.access(p, os.W_OK):
        raise ConfigError("file is read-only", p, key=option, hint="remove it or choose another name")
    return p


def write_atomic(path: str | Path, write: Callable[[Path], None], option: str = "output") -> Path:
    """Call `write(tmp)` on a temporary file beside `path`, then rename it over `path` (all or nothing)."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = _new_file_beside(p)
    except OSError as exc:
        raise ConfigError(f"cannot write: {exc.strerror or exc}", p, key=option) from None
    try:
        write(Path(tmp))
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except OSError as exc:
        raise ConfigError(
            f"cannot write: {exc.strerror or exc}", p, key=option, hint="the previous file, if any, is unchanged"
        ) from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return p


def _new_file_beside(p: Path) -> str:
    """Create an empty, new temporary file in `p`'s directory; its mode follows the umask, as `open` would.

    (tempfile.mkstemp creates 0600 files whatever the umask: renamed over `p`, that would hide
    every output from the user's group.)
    """
    for _ in range(100):
        tmp = str(p.parent / f".{p.name}.{secrets.token_hex(4)}.tmp{p.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # the kernel applies the umask
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name beside {p}")
