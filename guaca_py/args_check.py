"""Checks of `guaca` options that argparse cannot express, run before anything is rendered."""

from __future__ import annotations

import math
import os
from pathlib import Path

from .errors import ConfigError
from .numeric import Range
from .output import IMAGE_SUFFIXES, active_reads, check_distinct, check_writable

#: settings reach shaders and buffers as 32-bit integers: a larger integer given with --set is refused here
SET_INT_MIN, SET_INT_MAX = -(2**31), 2**31 - 1


#: most frames --frames or --warmup asks for: each timed frame's pass times are kept for the medians, and a
#: count of ten digits (a typo) would run for months
MAX_FRAMES = 1_000_000


def _at_least(value: int | None, lo: int, option: str, hint: str, hi: int | None = None) -> None:
    problem = None if value is None else Range(lo, hi).problem(value)
    if problem:
        raise ConfigError(problem, key=option, hint=hint)


def check_method_option(method: str | None) -> None:
    """Refuse an unknown --method under the option's name (before a context is made)."""
    from .methods import require_method_id

    if method is not None:
        require_method_id(method, "--method")


def parse_set_option(item: str) -> tuple[str, object]:
    """KEY and the YAML value of one `--set KEY=VALUE`; a malformed item is refused under its own text."""
    from .yaml_source import yaml_value

    key, sep, text = item.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"expects KEY=VALUE, got {item!r}", key="--set", hint="e.g. --set budget_mb=64")
    try:  # read as a pipeline file's value is: bounded nesting and aliases, plain tags only
        value = yaml_value(text, "--set")
    except ConfigError as exc:
        shown = text if len(text) <= 40 else text[:37] + "..."
        raise ConfigError(f"cannot read {shown!r}: {exc.reason}", key="--set", hint="e.g. --set budget_mb=64") from None
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{text!r} is not a finite number", key=f"--set {item}", hint="e.g. --set budget_mb=64")
    if isinstance(value, int) and not isinstance(value, bool) and not SET_INT_MIN <= value <= SET_INT_MAX:
        raise ConfigError(
            f"{value} does not fit the 32-bit integer the setting is stored in",
            key=f"--set {item}",
            hint=f"give a number from {SET_INT_MIN} to {SET_INT_MAX}",
        )
    return key.strip(), value


def _path_given(path: str | None, option: str, hint: str) -> None:
    """Refuse an empty path (`''` would otherwise read as 'not given' or as the current folder)."""
    if path is not None and not path.strip():
        raise ConfigError("the path is empty", key=option, hint=hint)


def _label_inputs(args) -> None:
    """Name the scene and pipeline files among the run's inputs: an output naming one is refused before loading."""
    log = active_reads()
    if log is None:
        return
    if args.scene:
        log.label(args.scene, "the scene file")
    if args.pipeline and os.path.isfile(args.pipeline):
        log.label(args.pipeline, "the pipeline file")


def _check_inputs(args) -> None:
    """The scene, pipeline and material options: no empty path, material folders that exist and can be read."""
    check_method_option(args.method)
    _path_given(args.scene, "scene", "give a scene file, or leave it out for the built-in demo")
    _path_given(args.pipeline, "--pipeline", "give a pipeline YAML or a built-in name: default, exact")
    for d in getattr(args, "materials", None) or []:
        _path_given(d, "--materials", "give a directory of material descriptions")
        if not Path(d).is_dir():
            raise ConfigError("material directory not found", d, key="--materials", hint="give an existing directory")
        try:
            os.listdir(d)
        except OSError as exc:
            raise ConfigError(
                f"cannot read the directory: {exc.strerror or exc}", d, key="--materials", hint="check its permissions"
            ) from None
    _label_inputs(args)


def check_outputs(args) -> None:
    """`--out`/`--stats` writable, distinct and none of the run's inputs (those read so far, and the named ones)."""
    check_writable(args.out, "--out", IMAGE_SUFFIXES)
    if args.stats is not None:
        check_writable(args.stats, "--stats")
    check_distinct({"--out": args.out, "--stats": args.stats})


def check_render_args(args) -> None:
    """Reject bad numbers, unknown methods, missing directories and unwritable outputs with the option's name."""
    _check_inputs(args)
    _at_least(args.width, 1, "--width", "give the image width in pixels, e.g. --width 512")
    _at_least(args.height, 1, "--height", "give the image height in pixels, e.g. --height 512")
    _at_least(args.frames, 1, "--frames", "at least one frame is rendered and timed", MAX_FRAMES)
    _at_least(args.warmup, 0, "--warmup", "0 renders no untimed frames", MAX_FRAMES)
    check_outputs(args)


def check_view_args(args) -> None:
    """The same for `guaca view`: window size, frame count, the screenshot's path."""
    _check_inputs(args)
    _at_least(args.width, 1, "--width", "give the window width in pixels, e.g. --width 1024")
    _at_least(args.height, 1, "--height", "give the window height in pixels, e.g. --height 768")
    _at_least(args.frames, 0, "--frames", "0 runs until the window is closed", MAX_FRAMES)
    if args.screenshot is not None:
        check_writable(args.screenshot, "--screenshot", IMAGE_SUFFIXES)
