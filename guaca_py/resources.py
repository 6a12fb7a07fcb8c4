"""Locate built-in materials, shader templates and pipelines (installed or in a checkout)."""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent
KINDS = ("materials", "shader_templates", "pipelines")


def builtin_dir(kind: str) -> Path:
    """Directory of a built-in resource kind; wheels carry them under guaca_py/_builtin/."""
    if kind not in KINDS:
        raise ValueError(f"unknown resource kind {kind!r}")
    installed = _PKG / "_builtin" / kind
    if installed.is_dir():
        return installed
    checkout = _PKG.parent / kind  # editable install / source checkout
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"built-in {kind} not found under {installed} or {checkout}; reinstall guaca_py")


def builtin_pipeline(name: str) -> Path:
    """Path of a built-in pipeline config by name ('default', 'exact', ...)."""
    return builtin_dir("pipelines") / f"{name}.yaml"
