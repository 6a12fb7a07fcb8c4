"""Transparency methods: every OIT strategy of the same deferred pipeline, discovered by module."""

from __future__ import annotations

import importlib
import pkgutil

from ..errors import ConfigError
from .base import TransparencyMethod

_REGISTRY: dict[str, type[TransparencyMethod]] = {}


def _discover() -> None:
    if _REGISTRY:
        return
    for info in pkgutil.iter_modules(__path__):
        if info.name != "base":
            importlib.import_module(f"{__name__}.{info.name}")
    stack = list(TransparencyMethod.__subclasses__())
    while stack:
        cls = stack.pop()
        stack.extend(cls.__subclasses__())
        if getattr(cls, "id", None):
            _REGISTRY[cls.id] = cls


def method_ids() -> list[str]:
    """All method ids, in a stable order."""
    _discover()
    return sorted(_REGISTRY)


def require_method_id(mid: str, where: str) -> None:
    """Raise a ConfigError under `where` (the option or argument that gave it) unless `mid` is a method id."""
    if mid not in method_ids():
        raise ConfigError(f"unknown transparency method '{mid}'", where, hint=f"known: {', '.join(method_ids())}")


def method_class(mid: str) -> type[TransparencyMethod]:
    """The class implementing method `mid`."""
    _discover()
    return _REGISTRY[mid]


__all__ = ["TransparencyMethod", "method_ids", "method_class", "require_method_id"]
