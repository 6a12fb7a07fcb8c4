"""One registry for the library's pluggable classes: render passes and transparency methods.

A class registers itself where it is defined, with one decorator for both kinds:

    @register("pass")       # keyed by the class's `name` (the pipeline file's pass name)
    class BloomPass(FullscreenPass): ...

    @register("method")     # keyed by the class's `id` (transparency.method)
    class MyMethod(TransparencyMethod): ...

Config validation and the renderer look classes up here, so they need not import `passes` or
`methods`: this module imports nothing of the package but its errors. Importing `guaca_py`
imports both packages (guaca_py/__init__.py), and each package imports its modules, so every
class is registered before anything can ask for one. Materials are files, not classes: their
directory index is guaca_py/materials/registry.py.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from .errors import ConfigError

C = TypeVar("C", bound=type)


class Registry:
    """Classes of one kind by their key attribute, with the messages for names that are not there."""

    def __init__(self, kind: str, key_attr: str, noun: str, known: str):
        self.kind, self.key_attr, self.noun, self.known = kind, key_attr, noun, known
        self._classes: dict[str, type] = {}

    def add(self, cls: C) -> C:
        """Register `cls` under its key attribute; a second class with the same key is refused."""
        key = getattr(cls, self.key_attr, "")
        if not isinstance(key, str) or not key:
            raise TypeError(f"{cls.__qualname__} has no {self.key_attr} to register it as a {self.kind} by")
        held = self._classes.get(key)
        if held is not None and held is not cls:
            raise TypeError(
                f"{self.kind} '{key}' is registered twice: {held.__module__}.{held.__qualname__} "
                f"and {cls.__module__}.{cls.__qualname__}"
            )
        self._classes[key] = cls
        return cls

    def names(self) -> list[str]:
        """Every registered name, sorted (registration order depends on which module was imported first)."""
        return sorted(self._classes)

    def __contains__(self, name: object) -> bool:
        return name in self._classes

    def get(self, name: str) -> type:
        """The class registered as `name` (KeyError where there is none: check with `in` or require())."""
        return self._classes[name]

    def unknown(self, name: str) -> tuple[str, str]:
        """(reason, hint) for a name that is not registered: what it was and which ones are."""
        return f"unknown {self.noun} '{name}'", f"{self.known}: {', '.join(self.names())}"

    def require(self, name: str, where: str) -> type:
        """The class registered as `name`, or a ConfigError under `where` (the option or argument that gave it)."""
        if name not in self._classes:
            reason, hint = self.unknown(name)
            raise ConfigError(reason, where, hint=hint)
        return self._classes[name]


PASSES = Registry("pass", "name", "pass", "known passes")
METHODS = Registry("method", "id", "transparency method", "known")
_KINDS = {"pass": PASSES, "method": METHODS}


def register(kind: str) -> Callable[[C], C]:
    """Class decorator: register the class as a `kind` ('pass' or 'method') under its name or id."""
    if kind not in _KINDS:
        raise ValueError(f"unknown registry kind '{kind}' (known: {', '.join(_KINDS)})")
    return _KINDS[kind].add
