"""Tiny typed settings schema shared by passes and transparency methods."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


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
        if isinstance(value, bool) and bool not in self.types:
            return f"expected {'/'.join(t.__name__ for t in self.types)}, got {value!r}"
        if not isinstance(value, self.types) or (isinstance(value, str) and float in self.types and _numeric(value)):
            reason = f"expected {'/'.join(t.__name__ for t in self.types)}, got {value!r}"
            if isinstance(value, str) and _numeric(value) and (float in self.types or int in self.types):
                reason += f" (YAML reads {value!r} as text: write it with a dot and a signed exponent, e.g. "
                reason += f"{float(value):.1e})"
            return reason
        if self.choices is not None and value not in self.choices:
            return f"must be one of {', '.join(map(str, self.choices))}, got {value!r}"
        return self.check(value) if self.check else None


def _numeric(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return text.strip().lower() not in ("nan", "inf", "-inf", "+inf", "infinity")


def positive(v) -> str | None:
    """Check: value > 0."""
    return None if v > 0 else f"must be > 0, got {v}"


def non_negative(v) -> str | None:
    """Check: value >= 0."""
    return None if v >= 0 else f"must be >= 0, got {v}"


def unit_interval(v) -> str | None:
    """Check: 0 < value <= 1."""
    return None if 0 < v <= 1 else f"must be in (0, 1], got {v}"


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
        if key not in schema:
            raise error(key, f"unknown setting '{key}'", f"known: {', '.join(schema) or 'none'}")
        reason = schema[key].validate(value)
        if reason:
            raise error(key, reason, schema[key].doc or None)
        out[key] = value
    return out
