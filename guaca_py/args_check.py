"""Checks of `guaca render` options that argparse cannot express, run before anything is rendered."""

from __future__ import annotations

from pathlib import Path

from .errors import ConfigError
from .output import IMAGE_SUFFIXES, check_writable


def _at_least(value: int | None, lo: int, option: str, hint: str) -> None:
    if value is not None and value < lo:
        raise ConfigError(f"must be >= {lo}, got {value}", key=option, hint=hint)


def check_render_args(args) -> None:
    """Reject bad numbers, missing directories and unwritable outputs with the option's name."""
    _at_least(args.width, 1, "--width", "give the image width in pixels, e.g. --width 512")
    _at_least(args.height, 1, "--height", "give the image height in pixels, e.g. --height 512")
    _at_least(args.frames, 1, "--frames", "at least one frame is rendered and timed")
    _at_least(args.warmup, 0, "--warmup", "0 renders no untimed frames")
    for d in args.materials or []:
        if not Path(d).is_dir():
            raise ConfigError("material directory not found", d, key="--materials", hint="give an existing directory")
    check_writable(args.out, "--out", IMAGE_SUFFIXES)
    if args.stats:
        check_writable(args.stats, "--stats")
