"""Tiny typed settings schema shared by passes and transparency methods."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..numeric import NON_NEGATIVE, POSITIVE, Range, gpu_number_problem, yaml_number_hint


@dataclass(frozen=True)
class Setting:
    """One setting: accepted types, default, optional choices or check (returns reason or None)."""

    types: tuple
    default: Any
    doc: str = ""
    choices: tuple | None = None
    check: Callable[[Any], str | None] | None = None

    def validate(self, value) -> str | None:
        """Reason why `value` is invalid, or None."""
        expected = f"expected {'/'.join(t.__name__ for t in self.types)}, got {value!r}"
        if isinstance(value, bool) and bool not in self.types:
            return expected
        numeric = float in self.types or int in self.types
        hint = yaml_number_hint(value) if numeric else None
        # number text is refused even where text is accepted: YAML meant a number there
        if not isinstance(value, self.types) or (hint and float in self.types):
            return f"{expected} ({hint})" if hint else expected
        if numeric and isinstance(value, (int, float)):  # settings become uniforms and GLSL literals
            problem = gpu_number_problem(value, integer=float not in self.types)
            if problem:
                return problem
        if self.choices is not None and value not in self.choices:
            return f"must be one of {', '.join(map(str, self.choices))}, got {value!r}"
        return self.check(value) if self.check else None


def positive(v) -> str | None:
    """Check: value > 0."""
    return POSITIVE.problem(v)


def non_negative(v) -> str | None:
    """Check: value >= 0."""
    return NON_NEGATIVE.problem(v)


def unit_interval(v) -> str | None:
    """Check: 0 < value <= 1."""
    return UNIT_INTERVAL.problem(v)


UNIT_INTERVAL = Range(0, 1, lo_open=True)


def auto_or_positive_mb(v) -> str | None:
    """Check: 'auto' or a positive number of MB (storage budgets)."""
    if v == "auto" or (isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0):
        return None
    return f"must be 'auto' or a positive number of MB, got {v!r}"


NUMBER = (int, float)


def resolve_settings(schema: dict[str, Setting], given: dict, error) -> dict:
    """Defaults + given values; `error(key, reason, hint)` builds the exception for bad input."""
    out = {k: s.default for k, s in schema.items()}
    for key, value in (given or {}).items():
        if isinstance(value, np.generic):  # numpy's numbers from an embedding application: Python's
            value = value.item()
        if key not in schema:
            raise error(key, f"unknown setting '{key}'", f"known: {', '.join(schema) or 'none'}")
        reason = schema[key].validate(value)
        if reason:
            raise error(key, reason, schema[key].doc or None)
        out[key] = value
    return out
