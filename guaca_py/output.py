"""Output files: checked before a render starts, written atomically so a failure never truncates a good file.

An output never destroys anything else:

* it is a regular file or a new name: a directory, FIFO, device or socket is refused, and a
  symbolic link is written through (its target replaced, the link kept) only when it points at a
  regular file;
* it is none of the run's inputs: while `recording_reads()` is active (the `guaca` command runs
  every command inside it), every file the process opens for reading is noted through Python's
  audit hook on `open`, whatever loader opened it (scene, pipeline, material, GLSL, mesh,
  texture, glTF buffer), and an output naming one of them (same device and inode) is refused;
* two outputs of one run never name the same file (`check_distinct`);
* the new content goes to a short temporary name in the target's folder (`.gtmp-XXXXXXXX`, so any
  name the file system allows works), takes the replaced file's mode (a new file's follows the
  umask), and is renamed over the target; the temporary file is removed on any error, Ctrl-C,
  SIGTERM or SIGHUP.
"""

from __future__ import annotations

import os
import secrets
import signal
import stat
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from .errors import ConfigError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm")
TEMP_PREFIX = ".gtmp-"  # + 8 hex digits: 14 bytes, whatever the length of the target's name
# signals whose default action would end the process with the temporary file still there
_TERMINATING = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP", "SIGINT") if hasattr(signal, n))


def _kind(mode: int) -> str | None:
    """What a non-regular file is, in words; None for a regular file."""
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return None if stat.S_ISREG(mode) else "not a regular file"


def _path_limits(p: Path) -> tuple[int, int]:
    """(PATH_MAX, NAME_MAX) in bytes for `p`'s nearest existing folder (POSIX minimums where not reported)."""
    folder = p.parent
    while not os.path.isdir(folder) and folder != folder.parent:  # isdir: False, not an error, on any OSError
        folder = folder.parent
    try:
        return os.pathconf(folder, "PC_PATH_MAX"), os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        return 4096, 255


def _checked_text(path: str | Path, option: str) -> Path:
    """`path` as a Path, refused when empty, holding a NUL, naming a folder, or too long for the system."""
    text = os.fspath(path)
    if not text:
        raise ConfigError("the path is empty", key=option, hint="give a file name, e.g. out.png")
    if "\0" in text:
        raise ConfigError("the path holds a NUL character", key=option, hint="give a plain file name")
    if text.endswith(("/", os.sep)):
        raise ConfigError("names a directory", text, key=option, hint="give a file name inside it, e.g. DIR/out.png")
    p = Path(text)
    path_max, name_max = _path_limits(p)
    size = len(os.fsencode(text))
    if size >= path_max:
        raise ConfigError(
            f"the path is {size} bytes; the system takes at most {path_max - 1}",
            f"{text[:40]}...",
            key=option,
            hint="choose a shorter path",
        )
    for part in p.parts:
        if len(os.fsencode(part)) > name_max:
            raise ConfigError(
                f"a name in the path is {len(os.fsencode(part))} bytes; the file system takes at most {name_max}",
                f"{text[:40]}...",
                key=option,
                hint="choose a shorter name",
            )
    return p


def _target(p: Path, option: str) -> tuple[Path, os.stat_result | None]:
    """The file a write to `p` replaces (a symbolic link's regular target) and its status (None: a new file)."""
    try:
        st = os.lstat(p)
    except (FileNotFoundError, NotADirectoryError):  # a new file (a folder that is a file: check_writable says so)
        return p, None
    except OSError as exc:
        raise ConfigError(f"cannot use this path: {exc.strerror or exc}", p, key=option) from None
    link = stat.S_ISLNK(st.st_mode)
    if link:
        try:
            st = os.stat(p)  # what the chain of links ends at (/proc's links to pipes and terminals too)
        except OSError as exc:
            why = "a missing file" if isinstance(exc, FileNotFoundError) else f"nothing ({exc.strerror or exc})"
            raise ConfigError(
                f"is a symbolic link to {why}",
                p,
                key=option,
                hint="a link is written through only to a regular file; remove it or choose another name",
            ) from None
    kind = _kind(st.st_mode)
    via = " (through a symbolic link)" if link else ""
    if kind == "a directory":
        raise ConfigError(f"is a directory{via}", p, key=option, hint="give a file name inside it, e.g. DIR/out.png")
    if kind is not None:
        raise ConfigError(
            f"is {kind}{via}, not a regular file",
            p,
            key=option,
            hint="outputs are written to regular files only; choose a file name",
        )
    if not link:
        return p, st
    real = Path(os.path.realpath(p))  # the file to replace, so that the link stays a link
    try:
        same = os.path.samefile(real, p)
    except OSError:
        same = False
    if not same:  # a link that changed under us, or one realpath cannot spell
        raise ConfigError("is a symbolic link whose target cannot be resolved", p, key=option, hint="give the target")
    return real, st


def check_writable(path: str | Path, option: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """Fail now, before minutes of rendering, if `path` cannot be written or would destroy another file."""
    p = _checked_text(path, option)
    target, st = _target(p, option)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        got = f"'{p.suffix}'" if p.suffix else "no extension"
        raise ConfigError(
            f"cannot tell the image format from {got}", p, key=option, hint=f"end the name with {', '.join(suffixes)}"
        )
    parent = target.parent
    for up in (parent, *parent.parents):
        if up.exists():
            if not up.is_dir():
                raise ConfigError(f"{up} is a file, not a directory", p, key=option, hint="choose another path")
            if not os.access(up, os.W_OK | os.X_OK):
                raise ConfigError(f"directory {up} is not writable", p, key=option, hint="choose a writable place")
            break
    if st is not None and not os.access(target, os.W_OK):
        raise ConfigError("file is read-only", p, key=option, hint="remove it or choose another name")
    if st is not None:
        _refuse_input(st, p, option)
    return p


def check_distinct(outputs: dict[str, str | Path | None]) -> None:
    """Refuse two options (e.g. --out and --stats) naming one file: the second write would replace the first."""
    seen: list[tuple[str, str | Path]] = []
    for option, path in outputs.items():
        if path is None:
            continue
        for other, earlier in seen:
            if _same_file(path, earlier):
                raise ConfigError(
                    f"names the same file as {other}", path, key=option, hint="give each output its own name"
                )
        seen.append((option, path))


def _same_file(a: str | Path, b: str | Path) -> bool:
    """Whether `a` and `b` are one file: the same inode where both exist, else the same resolved path."""
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return os.path.realpath(a) == os.path.realpath(b)


# ---------------------------------------------------------------------------- the run's inputs
class ReadLog:
    """The files opened for reading while it is active (absolute paths), and names for some of them."""

    def __init__(self) -> None:
        self.paths: set[str] = set()
        self.labels: dict[str, str] = {}
        self.own: set[str] = set()  # folders of the run's own outputs (each ending in a separator)

    def own_folder(self, path: str | Path) -> None:
        """Files under `path` are the run's own outputs: reading them back (a resumed batch job) makes no input."""
        self.own.add(os.path.join(os.path.abspath(path), ""))

    def label(self, path: str | Path | None, what: str) -> None:
        """Name an input the run will read (e.g. 'the scene file'): refused as an output even before it is opened."""
        if path is not None and os.fspath(path):
            self.labels[os.path.abspath(path)] = what

    def clash(self, st: os.stat_result) -> str | None:
        """How the file of status `st` is an input of this run, or None when it is not one."""
        key = (st.st_dev, st.st_ino)
        for path in (*self.labels, *list(self.paths)):
            try:
                other = os.stat(path)
            except (OSError, ValueError):
                continue
            if (other.st_dev, other.st_ino) == key:
                what = self.labels.get(path)
                return f"is {what}" if what else f"is an input of this run (read as {path})"
        return None


_logs: list[ReadLog] = []
_hooked = False


def _audit(event: str, args: tuple) -> None:
    """Python's audit hook: note each file opened read-only while a ReadLog is active."""
    if event != "open" or not _logs:
        return
    path, _mode, flags = args
    if isinstance(path, int) or path is None or flags & (os.O_WRONLY | os.O_RDWR):
        return
    with suppress(TypeError, ValueError):
        log, full = _logs[-1], os.path.abspath(os.fsdecode(path))
        if not any(full.startswith(folder) for folder in log.own):
            log.paths.add(full)


@contextmanager
def recording_reads() -> Iterator[ReadLog]:
    """Note every file read inside the block; `check_writable` and `write_atomic` refuse to replace one."""
    global _hooked
    if not _hooked:  # an audit hook stays for the life of the process: one, idle while no log is active
        sys.addaudithook(_audit)
        _hooked = True
    log = ReadLog()
    _logs.append(log)
    try:
        yield log
    finally:
        _logs.remove(log)


def active_reads() -> ReadLog | None:
    """The innermost active ReadLog, or None outside `recording_reads()`."""
    return _logs[-1] if _logs else None


def _refuse_input(st: os.stat_result, p: Path, option: str) -> None:
    """ConfigError when the existing file of status `st` is an input of the recorded run."""
    log = active_reads()
    clash = log.clash(st) if log is not None else None
    if clash:
        raise ConfigError(
            f"{clash}: writing the output would destroy it", p, key=option, hint="choose another output name"
        )


# ---------------------------------------------------------------------------- writing
class _Signalled(BaseException):
    """A terminating signal arrived while a temporary file existed (raised by the handler, to clean up)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_signalled(signum, _frame) -> None:
    raise _Signalled(signum)


@contextmanager
def _cleanup_on_signals() -> Iterator[None]:
    """Turn SIGTERM/SIGHUP (and SIGINT where it would kill) into an exception for the block's cleanup.

    Only signals at their default action are caught, and only in the main thread (where Python runs
    handlers); after the cleanup the signal is raised again at its default action, so the process
    ends as it would have, minus the temporary file. Handlers the application installed stay.
    """
    saved: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in _TERMINATING:
            if signal.getsignal(sig) == signal.SIG_DFL:
                saved[sig] = signal.signal(sig, _raise_signalled)
    try:
        yield
    except _Signalled as s:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        saved.clear()
        os.kill(os.getpid(), s.signum)  # at its default action again: ends the process
        raise SystemExit(128 + s.signum) from None
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


@contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold the terminating signals back for a few statements (delivered, and handled, right after)."""
    block = threading.current_thread() is threading.main_thread() and hasattr(signal, "pthread_sigmask")
    if block:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _TERMINATING)
    try:
        yield
    finally:
        if block:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


def write_atomic(path: str | Path, write: Callable[[Path], None], option: str = "output") -> Path:
    """Call `write(tmp)` on a temporary file beside `path`'s target, then rename it over the target (all or nothing).

    Refused (ConfigError) as `check_writable` refuses; a replaced file keeps its mode (and owner
    where the process may set it), a new one gets 0666 less the umask.
    """
    p = _checked_text(path, option)
    target, old = _target(p, option)
    if old is not None:
        _refuse_input(old, p, option)
    with _cleanup_on_signals():
        tmp: str | None = None
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            with _signals_deferred():  # the file and the name that cleans it up come into being together
                tmp = _new_file_beside(target)
            write(Path(tmp))
            if old is not None:
                _keep_owner_and_mode(tmp, old)
            with open(tmp, "rb+") as f:
                os.fsync(f.fileno())
            with _signals_deferred():  # renamed means nothing left to clean up
                os.replace(tmp, target)
                tmp = None
            _sync_folder(target.parent)
        except OSError as exc:
            raise ConfigError(
                f"cannot write: {exc.strerror or exc}", p, key=option, hint="the previous file, if any, is unchanged"
            ) from None
        finally:
            if tmp is not None:
                with suppress(OSError):
                    os.unlink(tmp)
    return p


def _keep_owner_and_mode(tmp: str, old: os.stat_result) -> None:
    """Give the temporary file the replaced file's owner (where permitted) and permission bits."""
    st = os.stat(tmp)
    if (st.st_uid, st.st_gid) != (old.st_uid, old.st_gid):
        with suppress(OSError):  # only root may give a file away; a group the user is in is allowed too
            os.chown(tmp, old.st_uid, old.st_gid)
    os.chmod(tmp, stat.S_IMODE(old.st_mode))  # after chown, which clears set-id bits


def _sync_folder(folder: Path) -> None:
    """Make the rename durable (best effort: some file systems cannot sync a folder)."""
    with suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _new_file_beside(p: Path) -> str:
    """Create an empty, new temporary file in `p`'s directory; its mode follows the umask, as `open` would.

    (tempfile.mkstemp creates 0600 files whatever the umask: renamed over `p`, that would hide
    every output from the user's group.) The name has a fixed, short length, so a target whose own
    name is as long as the file system allows still has a temporary beside it.
    """
    for _ in range(100):
        tmp = os.path.join(p.parent, f"{TEMP_PREFIX}{secrets.token_hex(4)}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # the kernel applies the umask
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name beside {p}")
