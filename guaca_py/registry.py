"""One registry for what pipelines name: render passes and transparency methods.

Each registers itself where it is defined, with one decorator for both kinds:

    @register("pass")       # a Pass class, keyed by its `name` (the pipeline file's pass name)
    class BloomPass(FullscreenPass): ...

    register("method")(MethodSpec("my_method", "what it does", MyMethod, options))
                            # keyed by the spec's `id` (transparency.method); one class may
                            # implement several methods, each a spec with its own options

Config validation and the renderer look entries up here, so they need not import `passes` or
`methods`: this module imports nothing of the package but its errors. Importing `guaca_py`
imports both packages (guaca_py/__init__.py), and each package imports its modules, so every
entry is registered before anything can ask for one. Materials are files, not classes: their
directory index is guaca_py/materials/registry.py.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from .errors import ConfigError

T = TypeVar("T")


def _describe(entry: object) -> str:
    """Where an entry is defined: a class by its module and name, a spec by the class implementing it."""
    cls = entry if isinstance(entry, type) else getattr(entry, "impl", type(entry))
    return f"{cls.__module__}.{cls.__qualname__}"


class Registry:
    """Entries of one kind by their key attribute, with the messages for names that are not there."""

    def __init__(self, kind: str, key_attr: str, noun: str, known: str):
        self.kind, self.key_attr, self.noun, self.known = kind, key_attr, noun, known
        self._entries: dict[str, Any] = {}

    def add(self, entry: T) -> T:
        """Register `entry` under its key attribute; a second entry with the same key is refused."""
        key = getattr(entry, self.key_attr, "")
        if not isinstance(key, str) or not key:
            raise TypeError(f"{_describe(entry)} has no {self.key_attr} to register it as a {self.kind} by")
        held = self._entries.get(key)
        if held is not None and held is not entry:
            raise TypeError(f"{self.kind} '{key}' is registered twice: {_describe(held)} and {_describe(entry)}")
        self._entries[key] = entry
        return entry

    def names(self) -> list[str]:
        """Every registered name, sorted (registration order depends on which module was imported first)."""
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def get(self, name: str) -> Any:
        """The entry registered as `name` (KeyError where there is none: check with `in` or require())."""
        return self._entries[name]

    def unknown(self, name: str) -> tuple[str, str]:
        """(reason, hint) for a name that is not registered: what it was and which ones are."""
        return f"unknown {self.noun} '{name}'", f"{self.known}: {', '.join(self.names())}"

    def require(self, name: str, where: str) -> Any:
        """The entry registered as `name`, or a ConfigError under `where` (the option or argument that gave it)."""
        if name not in self._entries:
            reason, hint = self.unknown(name)
            raise ConfigError(reason, where, hint=hint)
        return self._entries[name]


PASSES = Registry("pass", "name", "pass", "known passes")
METHODS = Registry("method", "id", "transparency method", "known")
_KINDS = {"pass": PASSES, "method": METHODS}


# `transparency.method: auto` names no registered method: the Renderer picks one of AUTO_CANDIDATES
# on the device (guaca_py/methods/auto.py, which adds the ids its measured tables rank when imported)
AUTO = "auto"
AUTO_CANDIDATES: set[str] = set()


def settings_schema(mid: str) -> dict:
    """Settings `transparency.method: mid` accepts (`auto`: auto_settings_schema)."""
    return auto_settings_schema() if mid == AUTO else METHODS.get(mid).settings_schema()


def auto_settings_schema() -> dict:
    """Settings `method: auto` accepts: those of any method it may pick (the one picked takes its own)."""
    schema: dict = {}
    for mid in sorted(AUTO_CANDIDATES):
        for key, setting in METHODS.get(mid).settings_schema().items():
            schema.setdefault(key, setting)
    return schema


def unknown_method(mid: str) -> tuple[str, str]:
    """(reason, hint) for a transparency.method that is neither a method id nor 'auto'."""
    reason, hint = METHODS.unknown(mid)
    return reason, f"{hint}; or {AUTO} (the fastest exact method measured on the device)"


def register(kind: str) -> Callable[[T], T]:
    """Decorator: register a pass class (kind 'pass', by its name) or a MethodSpec (kind 'method', by its id)."""
    if kind not in _KINDS:
        raise ValueError(f"unknown registry kind '{kind}' (known: {', '.join(_KINDS)})")
    return _KINDS[kind].add
