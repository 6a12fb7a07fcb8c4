"""Batch jobs: the YAML description (scenes, camera path, node animation, variants) checked with file, line and key.

Job file format
---------------

::

    scene: scene.yaml                 # relative to the job file; a list renders each scene
    frames: 48                        # optional with `camera: {list: ...}` (its length)
    camera:                           # one of orbit, keyframes, list; omitted: the scene's camera
      orbit: {target: [0, 0, 0], radius: 5, height: 1.5, degrees: 360}
    animate:                          # optional: node transforms interpolated over the frames
      - node: pane_a                  # a node name of the scene
        keyframes:
          - {frame: 0, rotation_deg: [0, 0, 0]}
          - {frame: 47, rotation_deg: [0, 360, 0], translation: [0, 1, 0]}
    resolution: [256, 192]            # default: each variant's pipeline resolution
    variants:                         # default: one variant `default` (the default pipeline)
      - {name: exact, pipeline: exact}
      - {name: fast, set: {threshold: 0.95}}
      - {name: aa4, method: presort_lf, set: {antialiasing.samples: 4}, resolution: [128, 96]}
    video: false                      # true: DIR/<variant>.mp4 as well (pip install "guaca_py[video]")
    fps: 24                           # frames per second of the videos
    png_level: 1                      # zlib level of the PNGs, 0-9 (the pixels are the same at every level)

Camera paths
    ``orbit``: frame i at θ = degrees·i/frames, position = target + (radius·sin θ, height,
    radius·cos θ), looking at target; fov_y, near, far and up are the scene camera's. target,
    radius and height default to the scene camera's (its target, its horizontal distance from
    it and its height above it), degrees to 360. ``keyframes``: a list of ``{frame: I, position,
    target, up, fov_y, near, far}`` (each key optional but frame; a missing one is the scene
    camera's), linearly interpolated, held before the first and after the last. ``list``: one
    camera mapping per frame.

Variants
    ``name`` (folder-safe, unique), ``pipeline`` (built-in name or a YAML path relative to the
    job file), ``method`` (a transparency method id), ``set`` (pipeline settings like the
    command line's ``--set KEY=VALUE``: transparency ones, bare or ``transparency.``-prefixed,
    and ``antialiasing.*``) and ``resolution``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..antialiasing import method_refusal, with_settings
from ..errors import ConfigError
from ..numeric import POSITIVE, Range, number_hint, yaml_number_hint
from ..pipeline.config import PipelineConfig, load_pipeline
from ..registry import METHODS
from ..resources import builtin_pipeline
from ..yaml_source import Located, load_yaml_file

TOP_KEYS = ("scene", "frames", "camera", "animate", "resolution", "variants", "video", "fps", "png_level")
CAMERA_PATHS = ("orbit", "keyframes", "list")
ORBIT_KEYS = ("target", "radius", "height", "degrees")
CAMERA_KEYS = ("position", "target", "up", "fov_y", "near", "far")
VARIANT_KEYS = ("name", "pipeline", "method", "set", "resolution")
TRANSFORM_KEYS = ("translation", "rotation_deg", "scale")
NAME_PATTERN = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
MAX_FRAMES = 1_000_000  # frame numbers are written with five digits or more; a million is plenty
FOV = Range(0, 180, lo_open=True, hi_open=True)
MAX_SIZE = 16384


@dataclass(frozen=True)
class Variant:
    """One way of rendering every frame: a pipeline with its method and settings, and a resolution."""

    name: str
    pipeline: PipelineConfig  # with the variant's antialiasing settings applied
    method: str | None
    overrides: dict  # transparency settings, checked
    resolution: tuple[int, int] | None

    def fingerprint(self) -> str:
        """A digest of everything that decides this variant's pixels (for the rerun check)."""
        text = json.dumps([dataclasses.asdict(self.pipeline), self.method, self.overrides], sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class Keyframe:
    """Values given at one frame (a subset of a camera's or a transform's keys)."""

    frame: int
    values: dict[str, Any]
    line: int | None


@dataclass
class Job:
    """A checked batch job; `doc` keeps the lines for errors found once the scenes are loaded."""

    doc: Located
    scenes: list[Path]
    frames: int
    camera: tuple[str, Any] | None  # ("orbit", {...}), ("keyframes", [Keyframe]), ("list", [dict]) or None
    animate: list[tuple[str, list[Keyframe], tuple]]  # (node name, keyframes, key path of the entry)
    resolution: tuple[int, int] | None
    variants: list[Variant]
    video: bool = False
    fps: float = 24.0
    scene_names: list[str] = field(default_factory=list)
    png_level: int = 1  # 1 encodes a 1024² dragons frame 4.4x faster than 6 (FrameResult.save's) for 13% more bytes

    @property
    def file(self) -> str:
        """The job file (or the name a dict job was given)."""
        return self.doc.file


class _Reader:
    """Checks values of a Located document; every error cites the file, the line and the key."""

    def __init__(self, doc: Located):
        self.doc = doc

    def error(self, path: tuple, reason: str, hint: str | None = None) -> ConfigError:
        return self.doc.error(path, reason, hint)

    def mapping(self, value: Any, path: tuple, allowed: tuple[str, ...], what: str) -> dict:
        if not isinstance(value, dict):
            raise self.error(path, f"expected a mapping for {what}, got {value!r}", f"keys: {', '.join(allowed)}")
        for key in value:
            if key not in allowed:
                raise self.error(path + (key,), f"unknown key {key!r} in {what}", f"valid keys: {', '.join(allowed)}")
        return value

    def number(self, value: Any, path: tuple, bounds: Range | None = None) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(path, f"expected a number, got {value!r}", number_hint(value))
        if not math.isfinite(value):
            raise self.error(path, f"expected a finite number, got {value}")
        if bounds is not None and not bounds.contains(value):
            raise self.error(path, f"must be {bounds.requirement()}, got {value}")
        return float(value)

    def integer(self, value: Any, path: tuple, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(path, f"expected a whole number, got {value!r}", yaml_number_hint(value))
        if not lo <= value <= hi:
            raise self.error(path, f"must be in [{lo}, {hi}], got {value}")
        return value

    def vector(self, value: Any, path: tuple, n: int = 3) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != n:
            raise self.error(path, f"expected a list of {n} numbers, got {value!r}", "e.g. [0, 1, 0]")
        return tuple(self.number(v, path + (i,)) for i, v in enumerate(value))

    def size(self, value: Any, path: tuple) -> tuple[int, int]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(path, f"expected [width, height], got {value!r}", "e.g. [256, 192]")
        w, h = (self.integer(v, path + (i,), 1, MAX_SIZE) for i, v in enumerate(value))
        return w, h

    def camera_values(self, value: Any, path: tuple, extra: tuple[str, ...] = ()) -> dict:
        """A camera mapping's checked values (any subset of CAMERA_KEYS)."""
        self.mapping(value, path, extra + CAMERA_KEYS, "a camera")
        out = {}
        for key in ("position", "target", "up"):
            if key in value:
                out[key] = self.vector(value[key], path + (key,))
        if "fov_y" in value:
            out["fov_y"] = self.number(value["fov_y"], path + ("fov_y",), FOV)
        for key in ("near", "far"):
            if key in value:
                out[key] = self.number(value[key], path + (key,), POSITIVE)
        return out

    def keyframes(self, value: Any, path: tuple, frames: int, read) -> list[Keyframe]:
        """Keyframes `{frame: I, ...}` in increasing frame order; `read(item, item_path)` checks the rest."""
        if not isinstance(value, list) or not value:
            raise self.error(path, "expected a list of keyframes", "e.g. [{frame: 0, ...}, {frame: 47, ...}]")
        out: list[Keyframe] = []
        for i, item in enumerate(value):
            at = path + (i,)
            if not isinstance(item, dict) or "frame" not in item:
                raise self.error(at, "a keyframe is a mapping with 'frame'", "e.g. {frame: 0, position: [0, 1, 5]}")
            frame = self.integer(item["frame"], at + ("frame",), 0, frames - 1)
            if out and frame <= out[-1].frame:
                raise self.error(at + ("frame",), f"frame {frame} does not follow frame {out[-1].frame}")
            out.append(Keyframe(frame, read({k: v for k, v in item.items() if k != "frame"}, at), self.doc.line(at)))
        return out


def _builtin_pipeline_names() -> list[str]:
    return sorted(p.stem for p in builtin_pipeline("default").parent.glob("*.yaml"))


def _variant(r: _Reader, value: Any, path: tuple, base: Path) -> Variant:
    """One variant: its pipeline loaded, `set` applied through the command line's checks, cited at the job's lines."""
    r.mapping(value, path, VARIANT_KEYS, "a variant")
    name = value.get("name")
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise r.error(
            path + ("name",), f"a variant needs a folder-safe name, got {name!r}", "letters, digits, '_', '-', '.'"
        )
    spec = value.get("pipeline", "default")
    if not isinstance(spec, str):
        raise r.error(path + ("pipeline",), f"expected a built-in name or a YAML path, got {spec!r}")
    file = base / spec
    if not Path(spec).suffix and not file.exists():
        if not builtin_pipeline(spec).is_file():
            raise r.error(
                path + ("pipeline",),
                f"no built-in pipeline '{spec}' and no such file",
                f"built-in: {', '.join(_builtin_pipeline_names())}; or a .yaml path relative to the job file",
            )
        pipeline = load_pipeline(builtin_pipeline(spec))
    elif not file.is_file():
        raise r.error(path + ("pipeline",), f"pipeline file not found: {file}", "paths are relative to the job file")
    else:
        pipeline = load_pipeline(file)  # its own errors cite its own file and line
    method = value.get("method")
    if method is not None and (not isinstance(method, str) or method not in METHODS):
        raise r.error(path + ("method",), *METHODS.unknown(str(method)))
    given = value.get("set") or {}
    if not isinstance(given, dict):
        raise r.error(path + ("set",), f"expected a mapping of settings, got {given!r}", "e.g. {threshold: 0.95}")
    pipeline, overrides = apply_set(
        pipeline, method, given, lambda key, e: r.error(path + ("set", key), e.reason, e.hint)
    )
    refusal = method_refusal(METHODS.get(method or pipeline.transparency["method"]), pipeline.antialiasing["samples"])
    if refusal:
        raise r.error(path, refusal)
    size = r.size(value["resolution"], path + ("resolution",)) if "resolution" in value else None
    return Variant(name, pipeline, method, overrides, size)


def apply_set(
    pipeline: PipelineConfig, method: str | None, given: dict, cite: Callable[[str, ConfigError], ConfigError]
) -> tuple[PipelineConfig, dict]:
    """The pipeline with `antialiasing.*` settings applied, and the transparency settings (like `--set`).

    The same split and the same checks as the command line's `--set KEY=VALUE`
    (`antialiasing.with_settings`, `renderer.method_settings`); a bad value's error is passed
    to `cite(key, error)`, which gives the error to raise (at the job file's line).
    """
    from ..renderer import method_settings

    mid = method or pipeline.transparency["method"]
    overrides = {}
    for key, value in given.items():
        try:
            if key.startswith("antialiasing."):
                pipeline = with_settings(pipeline, {key.removeprefix("antialiasing."): value}, "set")
                continue
            bare = key.removeprefix("transparency.")  # the settings live under the pipeline's `transparency:` key
            method_settings(mid, {}, {bare: value}, overrides_source="set")
            overrides[bare] = value
        except ConfigError as exc:
            raise cite(key, exc) from None
    return pipeline, overrides


def _camera(r: _Reader, value: Any, frames: int | None) -> tuple[tuple[str, Any] | None, int | None]:
    """The camera path and, for a list, its length."""
    if value is None:
        return None, frames
    r.mapping(value, ("camera",), CAMERA_PATHS, "the camera path")
    if len(value) != 1:
        raise r.error(("camera",), "give exactly one of orbit, keyframes, list", "e.g. camera: {orbit: {radius: 5}}")
    kind, spec = next(iter(value.items()))
    path = ("camera", kind)
    if kind == "orbit":
        r.mapping(spec, path, ORBIT_KEYS, "an orbit")
        orbit = {}
        if "target" in spec:
            orbit["target"] = r.vector(spec["target"], path + ("target",))
        if "radius" in spec:
            orbit["radius"] = r.number(spec["radius"], path + ("radius",), POSITIVE)
        if "height" in spec:
            orbit["height"] = r.number(spec["height"], path + ("height",))
        orbit["degrees"] = r.number(spec.get("degrees", 360.0), path + ("degrees",))
        return ("orbit", orbit), frames
    if kind == "list":
        if not isinstance(spec, list) or not spec:
            raise r.error(path, "expected a list of cameras", "e.g. [{position: [0, 1, 5], target: [0, 0, 0]}]")
        if frames is not None and frames != len(spec):
            raise r.error(("frames",), f"frames is {frames} but the camera list has {len(spec)}", "drop frames:")
        return ("list", [r.camera_values(c, path + (i,)) for i, c in enumerate(spec)]), len(spec)
    if frames is None:
        raise r.error(path, "needs 'frames': keyframes are placed on a number of frames", "e.g. frames: 48")
    return ("keyframes", r.keyframes(spec, path, frames, r.camera_values)), frames


def _animate(r: _Reader, value: Any, frames: int) -> list:
    if not isinstance(value, list):
        raise r.error(("animate",), "expected a list of node animations", "e.g. [{node: pane, keyframes: [...]}]")
    out = []

    def transform(item: dict, at: tuple) -> dict:
        r.mapping(item, at, ("frame",) + TRANSFORM_KEYS, "a node keyframe")
        values = {k: r.vector(item[k], at + (k,)) for k in ("translation", "rotation_deg") if k in item}
        if "scale" in item:
            s = item["scale"]
            values["scale"] = (
                (r.number(s, at + ("scale",)),) * 3 if not isinstance(s, list) else r.vector(s, at + ("scale",))
            )
        return values

    for i, entry in enumerate(value):
        at = ("animate", i)
        r.mapping(entry, at, ("node", "keyframes"), "a node animation")
        if not isinstance(entry.get("node"), str):
            raise r.error(at + ("node",), f"expected a node name, got {entry.get('node')!r}")
        out.append((entry["node"], r.keyframes(entry.get("keyframes"), at + ("keyframes",), frames, transform), at))
    return out


def parse_job(doc: Located, base: Path) -> Job:
    """Check a parsed job document (paths relative to `base`); errors cite file, line and key."""
    r = _Reader(doc)
    data = doc.data
    r.mapping(data, (), TOP_KEYS, "a batch job")
    if "scene" not in data:
        raise r.error((), "missing 'scene'", "e.g. scene: scene.yaml (relative to the job file)")
    given = data["scene"]
    items = [(given, ("scene",))] if isinstance(given, str) else None
    if isinstance(given, list) and given:
        items = [(s, ("scene", i)) for i, s in enumerate(given)]
    if items is None:
        raise r.error(("scene",), f"expected a scene path or a list of them, got {given!r}")
    scenes, names = [], []
    for s, at in items:
        if not isinstance(s, str):
            raise r.error(at, f"expected a scene path, got {s!r}")
        p = base / s
        if not p.is_file():
            raise r.error(at, f"scene file not found: {p}", "paths are relative to the job file")
        if p.stem in names:
            raise r.error(at, f"two scenes named '{p.stem}'", "each scene's images go to a folder named after its file")
        scenes.append(p)
        names.append(p.stem)
    frames = r.integer(data["frames"], ("frames",), 1, MAX_FRAMES) if "frames" in data else None
    camera, frames = _camera(r, data.get("camera"), frames)
    if frames is None:
        raise r.error(("frames",), "missing: how many frames to render", "e.g. frames: 48")
    animate = _animate(r, data["animate"], frames) if "animate" in data else []
    resolution = r.size(data["resolution"], ("resolution",)) if "resolution" in data else None
    raw = data.get("variants", [{"name": "default"}])
    if not isinstance(raw, list) or not raw:
        raise r.error(("variants",), "expected a list of variants", "e.g. [{name: exact, pipeline: exact}]")
    variants: list[Variant] = []
    for i, v in enumerate(raw):
        variant = _variant(r, v, ("variants", i), base)
        if any(x.name == variant.name for x in variants):
            raise r.error(("variants", i, "name"), f"two variants named '{variant.name}'", "names are folder names")
        variants.append(variant)
    video = data.get("video", False)
    if not isinstance(video, bool):
        raise r.error(("video",), f"expected true or false, got {video!r}")
    fps = r.number(data.get("fps", 24), ("fps",), POSITIVE)
    if video:
        _check_video(r, resolution, variants)
    level = r.integer(data.get("png_level", 1), ("png_level",), 0, 9)
    return Job(doc, scenes, frames, camera, animate, resolution, variants, video, fps, names, level)


def _check_video(r: _Reader, resolution, variants: list[Variant]) -> None:
    """Refuse video where it cannot be written: imageio-ffmpeg missing, odd sizes (H.264 takes even ones)."""
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise r.error(("video",), "needs imageio-ffmpeg", 'pip install "guaca_py[video]"') from None
    for i, v in enumerate(variants):
        size = v.resolution or resolution or v.pipeline.resolution
        if size[0] % 2 or size[1] % 2:
            at = ("variants", i, "resolution") if v.resolution else ("resolution",)
            raise r.error(at, f"video needs an even width and height, got {size[0]}x{size[1]}", "H.264 frames")


def load_job(job: str | Path | dict, base: str | Path | None = None) -> Job:
    """A Job from a YAML file, or from a dict of the same form (paths relative to `base`, default the cwd)."""
    if isinstance(job, dict):
        doc = Located(job, {(): None}, "<job>")  # no lines to cite: errors name the key
        return parse_job(doc, Path(base) if base is not None else Path.cwd())
    p = Path(job)
    return parse_job(load_yaml_file(p), p.parent)
