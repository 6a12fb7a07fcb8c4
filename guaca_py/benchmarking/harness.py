"""What every benchmark under benchmarks/ shares: the device, its results folder, arguments, progress.

Each benchmark writes one folder per device, benchmarks/results/<device>/<benchmark>/, overwritten
in place (git keeps the history): <benchmark>.json with every figure, <benchmark>.md with the
table and the command that wrote it, and a chart where matplotlib is installed. The device's
folder name is `h100` for an NVIDIA H100, `llvmpipe` for Mesa's software rasterizer, else a slug
of the GL renderer string.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import moderngl

from ..context import Capabilities, create_context
from .charts import pyplot

KNOWN_DEVICES = (("H100", "h100"), ("llvmpipe", "llvmpipe"))  # (in the GL renderer string, folder name)


def device_slug(renderer: str) -> str:
    """The results folder name of a GL renderer string: `h100`, `llvmpipe`, else a slug of the string."""
    for needle, slug in KNOWN_DEVICES:
        if needle.lower() in renderer.lower():
            return slug
    head = renderer.split("/")[0].split("(")[0]  # "NVIDIA H200/PCIe/SSE2", "llvmpipe (LLVM 15, 256 bits)"
    return re.sub(r"[^a-z0-9]+", "_", head.lower()).strip("_") or "unknown"


@dataclass
class Device:
    """A headless GL context for a benchmark's renderers, and what names its results."""

    ctx: moderngl.Context
    caps: Capabilities

    @property
    def name(self) -> str:
        """The GL renderer string."""
        return self.caps.gl_renderer

    @property
    def slug(self) -> str:
        """The results folder name (device_slug)."""
        return device_slug(self.caps.gl_renderer)

    def release(self) -> None:
        """Free the context (after every renderer on it is released)."""
        self.ctx.release()


def open_device(disable: tuple[str, ...] = ()) -> Device:
    """A new headless context (`disable`: capabilities to switch off, e.g. ("atomic_int64",))."""
    ctx, caps = create_context(None, disable)
    return Device(ctx, caps)


def bench_args(
    script: str, doc: str | None, *, size: int, frames: int = 8, scenes: bool = False
) -> argparse.ArgumentParser:
    """An argument parser with what every benchmark takes (results folder, size, frames, warm-up, --replot).

    `script` is the entry script's __file__: its name is the benchmark's, and the project root
    (its folder's parent) holds benchmarks/results/ and the scenes folder `.scenes/`.
    """
    ap = argparse.ArgumentParser(description=(doc or "").strip().splitlines()[0] if doc else None)
    ap.set_defaults(script=str(Path(script).resolve()))
    ap.add_argument("--out", type=Path, help="results folder (default: benchmarks/results/<device>/<benchmark>/)")
    ap.add_argument("--size", type=int, default=size, help="frame width and height in pixels")
    ap.add_argument("--frames", type=int, default=frames, help="timed frames per configuration (median)")
    ap.add_argument("--warmup", type=int, default=2, help="untimed frames at least (the first included)")
    ap.add_argument(
        "--warmup-s", type=float, default=1.5, help="untimed rendering before timing, GPU timers only (the clock ramps)"
    )
    ap.add_argument("--replot", action="store_true", help="no rendering: rebuild the table and chart from the JSON")
    if scenes:
        root = Path(script).resolve().parents[1]
        ap.add_argument("--scenes", type=Path, default=root / ".scenes", help="folder of scene YAMLs (default .scenes)")
        ap.add_argument("--scene-names", nargs="*", help="only these scenes (file stems)")
    return ap


def add_reference_args(ap: argparse.ArgumentParser, k: int = 8) -> None:
    """The supersampled reference's arguments (guaca_py.reference.exact_reference): --ref-k, --tile."""
    ap.add_argument("--ref-k", type=int, default=k, help="reference supersampling factor")
    ap.add_argument("--tile", type=int, default=2048, help="largest reference tile side in px")


def raster_overrides(raster: str) -> dict:
    """Method settings of a benchmark's `--raster` choice: `auto`, `hardware`, `compute`, or `compute/ORDER`
    (`compute/tile`: that rasterizer with that raster_order)."""
    kind, _, order = raster.partition("/")
    return {"raster": kind, **({"raster_order": order} if order else {})}


def scene_paths(args: argparse.Namespace) -> list[Path]:
    """The scene YAMLs of --scenes, only those of --scene-names (in that order) where given; exits if there are none."""
    if args.scene_names:
        paths = [args.scenes / f"{name}.yaml" for name in args.scene_names]
        missing = [str(p) for p in paths if not p.is_file()]
        if missing:
            raise SystemExit(f"scenes not found: {', '.join(missing)} (copy ../shared/scenes to .scenes/)")
        return paths
    if not args.scenes.is_dir():  # a run over no scenes would end in an empty report and exit status 0
        raise SystemExit(f"--scenes {args.scenes}: no such folder (copy ../shared/scenes to .scenes/)")
    paths = sorted(args.scenes.glob("*.yaml"))
    if not paths:
        raise SystemExit(f"--scenes {args.scenes}: no scene YAML (*.yaml) in this folder")
    return paths


class Results:
    """The results folder of one benchmark run: where it writes, the command that wrote it, the files."""

    def __init__(self, args: argparse.Namespace, device: str, argv: list[str] | None = None, name: str | None = None):
        script = Path(args.script)
        self.name = name or script.stem  # a mode of a script (paper_table.py scaling) names its own files
        self.device = device
        self.dir = args.out or script.parent / "results" / device_slug(device) / script.stem  # one folder a script
        argv = sys.argv[1:] if argv is None else argv
        self.command = f"python benchmarks/{script.name} {shlex.join(argv)}".rstrip()
        self.replot = False  # set by existing(): the record is read back, not measured

    @classmethod
    def existing(cls, args: argparse.Namespace, argv: list[str] | None = None, name: str | None = None) -> Results:
        """The folder a --replot reads and rewrites: --out, else this device's."""
        if args.out is not None:
            res = cls(args, "?", argv, name)
        else:
            device = open_device()
            try:
                res = cls(args, device.name, argv, name)
            finally:
                device.release()
        res.replot = True
        return res

    def path(self, suffix: str, stem: str | None = None) -> Path:
        """A file of the folder: <stem or benchmark name><suffix>."""
        return self.dir / f"{stem or self.name}{suffix}"

    def write_json(self, data: dict, stem: str | None = None) -> Path:
        """Write the record as <stem>.json, headed by this run's device and command (data's own are ignored)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.path(".json", stem)
        rec = {"device": self.device, "command": self.command}
        rec.update((k, v) for k, v in data.items() if k not in rec)
        path.write_text(json.dumps(rec, indent=1, default=str))
        return path

    def read_json(self, stem: str | None = None) -> dict:
        """The record a run wrote (for --replot)."""
        path = self.path(".json", stem)
        if not path.is_file():
            raise SystemExit(f"{path} does not exist: nothing to replot")
        return json.loads(path.read_text())

    def write_markdown(self, text: str, stem: str | None = None) -> Path:
        """Write <stem>.md."""
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.path(".md", stem)
        path.write_text(text if text.endswith("\n") else text + "\n")
        return path

    def write_chart(self, draw: Callable[[object], object], stem: str | None = None) -> Path | None:
        """Draw a chart with `draw(pyplot)` (it returns the figure) into <stem>.png; None without matplotlib."""
        plt = pyplot()
        if plt is None:
            print(f"matplotlib is not installed: no {self.path('.png', stem).name}", flush=True)
            return None
        fig = draw(plt)
        if fig is None:
            return None
        self.dir.mkdir(parents=True, exist_ok=True)
        path = self.path(".png", stem)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        return path

    def finish(
        self,
        rec: dict,
        markdown: Callable[[dict], str],
        chart: Callable[[dict], Callable[[object], object]] | None = None,
    ) -> str:
        """The end of a run or a --replot: a measured record is written as <name>.json (device and
        command beside it); then the page (`markdown(rec)`) and the chart (`chart(rec)`, a draw
        function for write_chart) from the record with its device and command. Returns the page."""
        measured = not self.replot
        if measured:
            self.write_json(rec)
            rec = {**rec, "device": self.device, "command": self.command}
        page = markdown(rec)
        written = [self.write_markdown(page)]
        if chart is not None:
            written.append(self.write_chart(chart(rec)))
        names = ", ".join(p.name for p in written if p is not None) + (f", {self.name}.json" if measured else "")
        print(f"wrote {self.dir}/: {names}", flush=True)
        return page


def header(title: str, device: str, command: str, timer: str | None) -> list[str]:
    """The opening lines of a benchmark's Markdown: title, device, what its times are, the command."""
    return [f"# {title}", "", f"Device: {device}. {timer_sentence(timer)}", "", f"Command: `{command}`", ""]


def timer_sentence(timer: str | None) -> str:
    """What the times of a table are, from the frames' stats["timer"] ("gpu" or "wall")."""
    if timer == "gpu":
        return "Times: GPU timer queries, ms."
    if timer == "wall":
        return (
            "Times: **wall time**, ms: this is a software rasterizer, which runs each pass on the CPU; "
            "no GPU performance figure."
        )
    return "No times."


def timer_of(rows: list[dict], key: str = "timer") -> str | None:
    """The timer kind of a set of rows: "wall" if any row was timed on the wall clock, else "gpu" or None."""
    kinds = {r.get(key) for r in rows if isinstance(r, dict) and r.get(key)}
    return "wall" if "wall" in kinds else ("gpu" if "gpu" in kinds else None)


class Progress:
    """Progress lines: step N of the total, time so far and the time left at the mean pace so far."""

    def __init__(self, total: int):
        self.total = max(1, total)
        self.done = 0
        self.t0 = time.perf_counter()

    def _stamp(self) -> str:
        return f"{time.perf_counter() - self.t0:7.1f} s"

    def step(self, text: str) -> None:
        """One more step done: print it with N/total and an ETA."""
        self.done += 1
        spent = time.perf_counter() - self.t0
        eta = spent / self.done * max(0, self.total - self.done)
        print(f"[{self.done:>3}/{self.total} {self._stamp()}, ETA {_duration(eta)}] {text}", flush=True)

    def note(self, text: str) -> None:
        """A line that is no step (a scene loaded, a reference rendered)."""
        print(f"[    {'':>{len(str(self.total))}} {self._stamp()}] {text}", flush=True)


def _duration(seconds: float) -> str:
    """Seconds as '42 s' or '3 min 05 s'."""
    s = int(round(seconds))
    return f"{s} s" if s < 60 else f"{s // 60} min {s % 60:02d} s"
