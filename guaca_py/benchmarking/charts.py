"""Charts of the benchmarks: matplotlib where installed (an optional dependency), plain-number log axes."""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # matplotlib is optional
    from matplotlib.axis import Axis


def pyplot() -> ModuleType | None:
    """matplotlib.pyplot on the file-only Agg backend, or None where matplotlib is not installed."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plain_log_axis(axis: Axis) -> None:
    """Label a log-scale matplotlib axis with plain numbers at 1, 2 and 5 per decade.

    Matplotlib's default labels powers of ten only across a wide range and every minor tick across a
    short one (2×10⁰ 3×10⁰ ...), where the labels run into each other; neither reads as a time.
    """
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def time_label(timer: str | None, what: str = "ms per frame") -> str:
    """An axis label for times from `timer` (a frame's stats["timer"]): GPU time, or wall time said as such."""
    if timer == "gpu":
        return f"GPU {what}"
    return f"wall-clock {what} (software rasterizer: no GPU time)"
