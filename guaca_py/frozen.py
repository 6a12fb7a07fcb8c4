"""Hashable stand-ins for user values, compared by value: the keys of every memo of what is derived from them.

Keys are the values themselves, never object identity, so a value edited in place (a list, an array) is
seen by the next comparison.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np

PLAIN = frozenset((float, int, bool, str, type(None)))  # hashable and compared by value as they are


def freeze(value):
    """A hashable stand-in for a value (lists and arrays become tuples, dicts sorted item tuples; objects stay)."""
    kind = type(value)
    if kind in PLAIN:
        return value
    if (kind is tuple or kind is list) and set(map(type, value)) <= PLAIN:
        return tuple(value)  # plain items as they are: the common case, a handful of calls a node a frame
    if isinstance(value, (list, tuple, np.ndarray)):
        return tuple(freeze(v) for v in value)
    if isinstance(value, dict):
        return tuple(sorted((k, freeze(v)) for k, v in value.items()))
    if isinstance(value, np.floating):
        return float(value)
    return value


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}  # per data class: dataclasses.fields() builds its tuple every call


def field_key(obj) -> tuple:
    """A data class instance's fields as (type, frozen value) pairs: equal keys, equal values of equal types (a
    check that refuses True where it takes 1.0 is not skipped by a key that compares them equal)."""
    names = _FIELD_NAMES.get(type(obj))
    if names is None:
        names = _FIELD_NAMES[type(obj)] = tuple(f.name for f in fields(obj))
    return tuple((type(v), freeze(v)) for v in map(obj.__getattribute__, names))
