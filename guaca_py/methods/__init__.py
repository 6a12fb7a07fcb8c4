"""Transparency methods: every OIT strategy of the same deferred pipeline.

Each method is a MethodSpec (its id, the class implementing it and that class's options)
registered with `register("method")` (guaca_py/registry.py) in the module of the class; importing
this package imports every such module.
"""

from __future__ import annotations

from ..errors import ConfigError
from ..registry import AUTO, METHODS, unknown_method
from . import (  # noqa: F401  (imported to register their methods)
    abuffer,
    approximate,
    auto,
    counted,
    kbuffer,
    peeling,
    peeling_coherent,
    peeling_multilayer,
)
from .base import MethodSpec, TransparencyMethod


def method_ids() -> list[str]:
    """All method ids, in a stable order."""
    return METHODS.names()


def require_method_id(mid: str, where: str) -> None:
    """Raise a ConfigError under `where` (the option or argument that gave it) unless `mid` is a method id or 'auto'."""
    if mid != AUTO and mid not in METHODS:
        reason, hint = unknown_method(mid)
        raise ConfigError(reason, where, hint=hint)


def method_class(mid: str) -> MethodSpec:
    """What builds method `mid`: call it as a class, spec(settings, caps); it answers the method's facts (exact, ...)."""
    return METHODS.get(mid)


__all__ = [
    "AUTO",
    "MethodSpec",
    "TransparencyMethod",
    "method_ids",
    "method_class",
    "require_method_id",
    "unknown_method",
]
