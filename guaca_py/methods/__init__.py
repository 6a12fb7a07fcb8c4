"""Transparency methods: every OIT strategy of the same deferred pipeline.

Each method class registers itself with `@register("method")` (guaca_py/registry.py); importing
this package imports every module that defines one.
"""

from __future__ import annotations

from ..registry import METHODS
from . import (  # noqa: F401  (imported to register their methods)
    abuffer_variants,
    approximate,
    counted,
    kbuffer,
    peeling,
    peeling_coherent,
    peeling_multilayer,
    presort_lf,
    stochastic,
)
from .base import TransparencyMethod


def method_ids() -> list[str]:
    """All method ids, in a stable order."""
    return METHODS.names()


def require_method_id(mid: str, where: str) -> None:
    """Raise a ConfigError under `where` (the option or argument that gave it) unless `mid` is a method id."""
    METHODS.require(mid, where)


def method_class(mid: str) -> type[TransparencyMethod]:
    """The class implementing method `mid`."""
    return METHODS.get(mid)


__all__ = ["TransparencyMethod", "method_ids", "method_class", "require_method_id"]
