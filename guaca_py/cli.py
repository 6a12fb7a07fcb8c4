"""Command line: `guaca render`, `guaca view`, `guaca batch`, `guaca info`, `guaca methods`."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import NoReturn

from .args_check import check_method_option, check_outputs, check_render_args, check_view_args, parse_set_option
from .batch.cli import add_parser as batch_parser
from .errors import ConfigError, GuacaError
from .output import recording_reads


def _options_over_pipeline(args):
    """The pipeline with --samples and `--set antialiasing.*` applied, and the `--set` transparency settings.

    Each value is checked under the option that gave it (`--samples`, `--set KEY=VALUE`), so an error
    never names the pipeline file for a value the file does not hold. A key without a prefix is the
    method's when the method has that setting, else antialiasing's when it has it (`--set supersample=2`).
    """
    from . import antialiasing
    from .pipeline.config import load_pipeline
    from .registry import settings_schema
    from .renderer import method_settings

    pipeline = load_pipeline(args.pipeline)
    mid = args.method or pipeline.transparency["method"]
    schema = settings_schema(mid)
    overrides = {}
    for item in args.set or []:
        key, value = parse_set_option(item)
        if key.startswith("antialiasing.") or (key in antialiasing.SETTINGS and key not in schema):
            given = {key.removeprefix("antialiasing."): value}
            pipeline = antialiasing.with_settings(pipeline, given, f"--set {item}")
            continue
        key = key.removeprefix("transparency.")  # the settings live under the pipeline's `transparency:` key
        method_settings(mid, {}, {key: value}, overrides_source=f"--set {item}")  # checked under the item
        overrides[key] = value
    if args.samples is not None:  # antialiasing.samples of the pipeline, overridden
        pipeline = antialiasing.with_samples(pipeline, args.samples, "--samples")
    return pipeline, overrides


def _cmd_render(args) -> int:
    from .limits import check_resolution
    from .renderer import Renderer
    from .scene.loader import demo_scene, load

    check_render_args(args)
    scene = load(args.scene) if args.scene is not None else demo_scene()  # YAML, glTF or a mesh file
    pipeline, overrides = _options_over_pipeline(args)
    renderer = Renderer(pipeline, method=args.method, method_overrides=overrides, material_paths=args.materials)
    try:
        width = renderer.config.resolution[0] if args.width is None else args.width
        height = renderer.config.resolution[1] if args.height is None else args.height
        given = args.width is not None or args.height is not None
        check_resolution(renderer.caps.limits, width, height, "--width/--height" if given else "resolution")
        check_outputs(args)  # again, before the render: every material, mesh and texture read so far is known
        if args.frames > 1 or args.warmup:
            from .benchmarking import measure

            m = measure(renderer, scene, width, height, args.warmup, args.frames)
            frame = m.last
            for name, ms in m.pass_ms.items():
                frame.stats["passes"][name]["ms"] = round(ms, 4)  # report medians
            frame.stats["timing"] = {"warmup": args.warmup, "frames": m.frames, "statistic": "median"}
        else:
            frame = renderer.render(scene, args.width, args.height)
        check_outputs(args)  # and after it (materials and textures load on first use): both files, or neither
        # every file first, then the report: a reader that stops early (`| head -1`) loses lines, not files
        out = frame.save(args.out)
        if args.stats is not None:
            frame.save_stats(args.stats)
    finally:
        renderer.release()
    s = frame.stats
    print(f"rendered {out} ({s['resolution'][0]}x{s['resolution'][1]}) on {s['device']}")
    timing = s.get("timing")
    how = f", median of {timing['frames']} frames after {timing['warmup']} warm-up" if timing else ", one frame"
    print(f"method {s['method']} ({s['insertion_path']} insertion), timer: {s['timer']}{how}")
    if s.get("method_auto"):
        print(f"  (method: auto) {s['method_auto']}")
    for name, p in s["passes"].items():
        print(f"  {name:<14} {p['ms']:10.3f} ms")
    ra = s.get("raster")
    if ra:
        order = f", triangle order {ra['compute']['order']}" if "compute" in ra else ""
        print(
            f"transparent raster ({ra['setting']}): {ra['compute_draws']} draws compute, "
            f"{ra['hardware_draws']} hardware{order}"
        )
    fr = s.get("fragments", {})
    print("fragments: " + ", ".join(f"{k} {v}" for k, v in fr.items()))
    mem = s.get("memory", {})
    print("memory: " + ", ".join(f"{k} {v / 1024:.1f} KiB" for k, v in mem.items() if not k.endswith("node_bytes")))
    if s.get("regrown"):
        print(f"A-buffer pool grown and frame re-rendered {s['regrown']} time(s)")
    for w in s.get("warnings", []):
        print(f"WARNING: {w}", file=sys.stderr)
    if args.stats is not None:
        print(f"stats written to {args.stats}")
    return 0


def _cmd_view(args) -> int:
    from .output import IMAGE_SUFFIXES, check_writable
    from .scene.loader import demo_scene, load
    from .viewer.window import run_viewer

    check_method_option(args.method)
    check_view_args(args)
    scene = load(args.scene) if args.scene is not None else demo_scene()
    if args.screenshot is not None:  # again, after loading: not one of the files the scene read either
        check_writable(args.screenshot, "--screenshot", IMAGE_SUFFIXES)
    try:
        viewer = run_viewer(
            scene,
            width=args.width,
            height=args.height,
            pipeline=args.pipeline,
            method=args.method,
            view=args.view,
            headless=args.headless,
            frames=args.frames,
            screenshot=args.screenshot,
        )
    except ConfigError as exc:  # the viewer names its argument; here it came from the option
        if exc.key != "screenshot":
            raise
        raise ConfigError(exc.reason, exc.file, exc.line, "--screenshot", exc.hint) from None
    for path in viewer.screenshots_taken:
        print(f"screenshot written to {path}")
    print(f"{viewer.frames} frames; " + " | ".join(viewer.status_lines()[:1]))
    return 0


def _cmd_info(args) -> int:
    from .context import probe_capabilities
    from .methods import auto
    from .raster.choice import device_rule, order_rule

    caps = probe_capabilities()  # released again: the caller's current context stays current
    d = caps.as_dict()
    method_auto, method_why = auto.choose(caps)
    if args.json:
        info = dict(
            d,
            insertion_path=caps.insertion_path,
            raster_auto=device_rule(caps),
            raster_order_auto=order_rule(),
            method_auto={"method": method_auto, "why": method_why},
        )
        print(json.dumps(info, indent=2))
        return 0
    print(f"device:    {caps.gl_renderer}")
    print(f"vendor:    {caps.vendor}")
    print(f"OpenGL:    {caps.version}")
    for k in ("atomic_int64", "fragment_interlock", "conservative_raster", "gpu_timers"):
        print(f"{k + ':':<22}{'yes' if d[k] else 'no'}")
    if caps.limits is not None:
        lim = caps.limits
        free = f"{lim.available_bytes / 2**20:.0f} MiB" if lim.available_bytes else "not reported"
        print(f"storage per buffer:   {lim.describe()}")
        print(f"  reported SSBO block {lim.reported_block_bytes / 2**20:.0f} MiB (advisory), free memory {free}")
        print(f"largest frame:        {lim.max_framebuffer[0]}x{lim.max_framebuffer[1]}")
    print(
        f"A-buffer insertion path: {caps.insertion_path} "
        f"({'64-bit atomicMax on (depth, pointer)' if caps.insertion_path == '64bit' else '32-bit CAS on immutable nodes'})"
    )
    print(f"transparency method (method: auto): {method_auto}, {method_why}")
    print(f"transparent raster (raster: auto): {device_rule(caps)}")
    print(f"compute triangle order (raster_order: auto): {order_rule()}")
    return 0


def _cmd_methods(args) -> int:
    from .context import probe_capabilities
    from .methods import method_class, method_ids

    caps = probe_capabilities()  # released again: the caller's current context stays current
    rows = []
    for mid in method_ids():
        cls = method_class(mid)
        reason = cls.unsupported_reason(caps)
        rows.append(
            (
                mid,
                "exact" if cls.exact else "approximate",
                cls.geometry_passes_rule if cls.geometry_passes is None else str(cls.geometry_passes),
                "yes" if cls.supports_antialiasing else "no",
                "yes" if reason is None else f"no: {reason}",
                cls.summary,
            )
        )
    print(f"{'id':<26}{'kind':<13}{'geometry passes':<17}{'samples > 1':<13}{'runs here':<12}summary")
    for r in rows:
        print(f"{r[0]:<26}{r[1]:<13}{r[2]:<17}{r[3]:<13}{r[4]:<12}{r[5]}")
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with guaca's error format: one line naming the argument, exit status 2 (no usage block)."""

    def error(self, message: str) -> NoReturn:
        """Print `error: PROG: MESSAGE (see PROG --help)` on stderr and exit 2."""
        self.exit(2, f"error: {self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the `guaca` command."""
    p = _Parser(prog="guaca", description="guaca_py: deferred shading with exact OIT")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a scene file (default: the built-in demo) to PNG")
    r.add_argument("scene", nargs="?", help="scene YAML, glTF or mesh file (default: built-in demo)")
    r.add_argument("--pipeline", default="default", help="pipeline YAML or built-in name (default, exact)")
    r.add_argument("--method", help="transparency method id (see `guaca methods`), or auto: the fastest exact one here")
    r.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="a transparency setting (e.g. --set budget_mb=1) or an antialiasing one (antialiasing.samples=4, "
        "supersample=2); repeatable",
    )
    r.add_argument("--width", type=int)
    r.add_argument("--height", type=int)
    r.add_argument("--samples", type=int, help="antialiasing samples per pixel (1, 2, 4, 8): overrides the pipeline's")
    r.add_argument("--out", default="out.png", help="output PNG (default out.png)")
    r.add_argument("--stats", help="write per-pass times, counters and memory as JSON")
    r.add_argument("--warmup", type=int, default=0, help="untimed frames before measuring")
    r.add_argument("--frames", type=int, default=1, help="timed frames; per-pass times are their medians")
    r.add_argument("--materials", action="append", help="extra directory of material descriptions")
    r.set_defaults(fn=_cmd_render)
    v = sub.add_parser("view", help="look at a scene interactively (orbit/fly camera, method and debug-view keys)")
    v.add_argument("scene", nargs="?", help="scene YAML, glTF or mesh file (default: built-in demo)")
    v.add_argument("--pipeline", default="default", help="pipeline YAML or built-in name (default, exact)")
    v.add_argument("--method", help="transparency method to start with, or auto (M / N keys switch)")
    v.add_argument("--view", default="shaded", choices=("shaded", "depth_complexity", "light_count"))
    v.add_argument("--width", type=int, default=1024)
    v.add_argument("--height", type=int, default=768)
    v.add_argument("--headless", action="store_true", help="no window: render off-screen (scripts, CI)")
    v.add_argument("--frames", type=int, default=0, help="stop after N frames (0: until closed; headless: 1)")
    v.add_argument("--screenshot", help="save the last frame's pixels (the first, without --frames) to this PNG")
    v.set_defaults(fn=_cmd_view)
    batch_parser(sub)  # `guaca batch`: options and run in guaca_py/batch/cli.py
    i = sub.add_parser("info", help="print the OpenGL device and its capabilities")
    i.add_argument("--json", action="store_true")
    i.set_defaults(fn=_cmd_info)
    m = sub.add_parser("methods", help="list transparency methods and whether this device runs them")
    m.set_defaults(fn=_cmd_methods)
    return p


#: exit status when the reader of stdout went away: 128 + SIGPIPE, as a shell reports a writer killed by it
BROKEN_PIPE_STATUS = 141
#: exit status after Ctrl-C: 128 + SIGINT, as a shell reports a command it interrupted
INTERRUPTED_STATUS = 130


#: where import's own code runs: a module being imported runs in a frame above one of these
_IMPORT_MACHINERY = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")
#: how long a Ctrl-C that landed in an import waits to be raised again, after it
_CTRL_C_RETRY_S = 0.002


def _importing(frame) -> bool:
    """Whether `frame` runs inside an import (import's machinery, or a module's code that it runs)."""
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_MACHINERY:
            return True
        frame = frame.f_back
    return False


def _ctrl_c(signum: int, frame) -> None:
    """Raise KeyboardInterrupt, except during an import: then raise it again a moment later, after it.

    An exception raised inside an import does not always reach the command: a lazy import drops
    its module lock through a weakref callback, which cannot propagate it (Python prints
    "Exception ignored" and goes on as if Ctrl-C had not been pressed), and some libraries guard
    their optional imports with `except BaseException`, keeping the interrupt as a broken module
    (trimesh: a TypeError, with a traceback, a moment later).
    """
    if _importing(frame):
        signal.setitimer(signal.ITIMER_REAL, _CTRL_C_RETRY_S)
        return
    raise KeyboardInterrupt


@contextmanager
def _ctrl_c_raised_outside_imports() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt where the command can act on it (main thread, Python's own handler)."""
    ours = (
        threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        and signal.getsignal(signal.SIGALRM) == signal.SIG_DFL
        and hasattr(signal, "setitimer")
    )
    if ours:
        signal.signal(signal.SIGINT, _ctrl_c)
        signal.signal(signal.SIGALRM, _ctrl_c)  # the retry: same handler, so it waits again if still in an import
    try:
        yield
    finally:
        if ours:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, signal.SIG_DFL)
            signal.signal(signal.SIGINT, signal.default_int_handler)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status: 2 bad input or device, 130 after Ctrl-C, 141 if stdout's reader left."""
    try:
        with _ctrl_c_raised_outside_imports():
            status = _run(build_parser().parse_args(argv))
        sys.stdout.flush()  # a closed pipe shows here at the latest, not in the interpreter's exit
        return status
    except BrokenPipeError:  # `guaca render | head -1`: the files are written, the rest of the report has no reader
        _discard_stdout()
        return BROKEN_PIPE_STATUS
    except KeyboardInterrupt:  # no traceback: a file being written was removed or left as it was (output.py)
        print("interrupted", file=sys.stderr)
        return INTERRUPTED_STATUS


def _discard_stdout() -> None:
    """Point stdout at /dev/null: Python flushes stdout again at exit, which would raise once more."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # not a file descriptor (a caller's capture): nothing to flush
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command; errors of input or device become a message and exit status 2.

    The command runs while the files it reads are recorded, so none of its outputs can replace one.
    """
    try:
        with recording_reads():
            return args.fn(args)
    except GuacaError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a file the input names cannot be read (missing, permissions, too long a path)
        if isinstance(exc, BrokenPipeError):  # stdout's reader went away: main's concern, not an input's
            raise
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:
        import moderngl

        # a resource the driver refused (incomplete framebuffer, out of memory) is a device limit
        if not isinstance(exc, moderngl.Error):
            raise
        hint = "lower the resolution or the scene's size"
        print(f"error: the OpenGL device refused the request: {exc} ({hint})", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
