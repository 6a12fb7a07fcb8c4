"""Numbers given by users: the allowed ranges they are checked against, and how to write one YAML read as text.

Every number that reaches the GPU is first checked by `gpu_number_problem`: finite, and within
the 32-bit type it becomes (a float32 uniform turns 1e39 into infinity; a 32-bit integer uniform
or GLSL literal cannot hold 1e11). Every check of a number against bounds (pass and method settings, `--width` and friends, material
uniform ranges, scene values, primitive parameters) tests `Range.contains` and names the bounds
with `str(Range)` or `Range.requirement`; each caller words its own sentence around them. YAML 1.1
reads an exponent without a dot and a sign ('1e30') as a string: `yaml_number_hint` says how to
write it, wherever such text reaches a number.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

PLAIN_NUMBER_HINT = "write a plain number like 1.5"


@dataclass(frozen=True)
class Range:
    """Allowed values from `lo` to `hi` (None: unbounded on that side), each end included unless open."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def contains(self, value: float) -> bool:
        """Whether `value` lies within the bounds (NaN lies within no bound)."""
        above = self.lo is None or (value > self.lo if self.lo_open else value >= self.lo)
        return above and (self.hi is None or (value < self.hi if self.hi_open else value <= self.hi))

    def __str__(self) -> str:
        """Interval notation, infinite ends written as such: '[0, 1]', '(0, inf]'."""
        lo = "-inf" if self.lo is None else f"{self.lo:g}"
        hi = "inf" if self.hi is None else f"{self.hi:g}"
        return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"

    def requirement(self) -> str:
        """The bounds as a requirement: '> 0' or '>= 1' for one bound, 'in (0, 1]' for two."""
        if self.hi is None and self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo is None and self.hi is not None:
            return f"{'<' if self.hi_open else '<='} {self.hi:g}"
        return f"in {self}"

    def problem(self, value: float) -> str | None:
        """'must be > 0, got -1' when `value` lies outside, else None (a settings check)."""
        return None if self.contains(value) else f"must be {self.requirement()}, got {value}"


POSITIVE = Range(0, lo_open=True)
NON_NEGATIVE = Range(0)
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
FLOAT32_MAX = 3.4028234663852886e38  # numpy.finfo(numpy.float32).max


def show_number(value: float) -> str:
    """`value` as text, a huge integer by its magnitude (str() refuses ints of more than 4,300 digits)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**16:
        return f"{'-' if value < 0 else ''}1e{int((abs(value).bit_length() - 1) * 0.30103)} (an integer)"
    return f"{value}"


def gpu_number_problem(value: float, integer: bool = False) -> str | None:
    """Why `value` cannot become a 32-bit GPU number (not finite; beyond int32 or float32), else None."""
    if integer:
        if isinstance(value, float) and not math.isfinite(value):
            return f"must be a finite integer, got {value}"
        if not INT32_MIN <= value <= INT32_MAX:
            return f"{show_number(value)} is beyond the 32-bit integer range [{INT32_MIN}, {INT32_MAX}]"
        return None
    try:
        number = float(value)
    except OverflowError:  # an int past 1.8e308
        return f"{show_number(value)} is beyond the 32-bit float range (magnitude at most {FLOAT32_MAX:.4g})"
    else:
        if not math.isfinite(number):
            return f"must be a finite number, got {value}"
    if abs(number) > FLOAT32_MAX:
        return f"{number:g} is beyond the 32-bit float range (magnitude at most {FLOAT32_MAX:.4g})"
    return None


_YAML_NUMBER = re.compile(  # what YAML 1.1 reads as a number when it is written without quotes
    r"^[-+]?(?:[0-9][0-9_]*\.[0-9_]*(?:[eE][-+][0-9]+)?|\.[0-9_]+(?:[eE][-+][0-9]+)?|0|[1-9][0-9_]*)$"
)


def yaml_number_hint(value: object) -> str | None:
    """How to write `value` as a number when it is text that reads as a finite number ('1e30'), else None."""
    if not isinstance(value, str):
        return None
    try:
        number = float(value)
    except ValueError:
        return None
    if not math.isfinite(number):  # 'nan', 'inf' and '1e999' are no exponent mistake
        return None
    if _YAML_NUMBER.match(value):  # a number YAML would read: the quotes made it text
        return f"{value!r} is quoted, so it is text: write it without quotes"
    if "e" not in value.lower():
        return f"write a plain number like {number:g}"
    return f"YAML reads {value!r} as text: write it with a dot and a signed exponent, e.g. {number:.1e}"


def number_hint(value: object) -> str:
    """The hint for a value given where a number belongs: `yaml_number_hint`'s, or write a plain number."""
    return yaml_number_hint(value) or PLAIN_NUMBER_HINT
