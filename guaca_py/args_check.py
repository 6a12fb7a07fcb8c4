"""Checks of `guaca render` options that argparse cannot express, run before anything is rendered."""

from __future__ import annotations

from pathlib import Path

from .errors import ConfigError
from .numeric import Range
from .output import IMAGE_SUFFIXES, check_writable


def _at_least(value: int | None, lo: int, option: str, hint: str) -> None:
    problem = None if value is None else Range(lo).problem(value)
    if problem:
        raise ConfigError(problem, key=option, hint=hint)


def check_method_option(method: str | None) -> None:
    """Refuse an unknown --method under the option's name (before a context is made)."""
    from .methods import require_method_id

    if method is not None:
        require_method_id(method, "--method")


def parse_set_option(item: str) -> tuple[str, object]:
    """KEY and the YAML value of one `--set KEY=VALUE`; a malformed item is refused under its own text."""
    import yaml

    key, sep, text = item.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"expects KEY=VALUE, got {item!r}", key="--set", hint="e.g. --set budget_mb=64")
    try:
        return key.strip(), yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"cannot read {text!r}: {exc}", key="--set", hint="e.g. --set budget_mb=64") from None


def check_render_args(args) -> None:
    """Reject bad numbers, unknown methods, missing directories and unwritable outputs with the option's name."""
    check_method_option(args.method)
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
