"""The library's environment variables: two names, read here and nowhere else (docs/architecture.md, Environment).

* `GUACA_MAX_BUFFER_MB` lowers the storage cap per buffer (guaca_py/limits.py applies it).
* `GUACA_RASTER_STAGES` (1 to enable) makes the compute rasterizer record each stage's GPU time.

Template variables never come from the environment: a program is a function of the scene, the
pipeline and the device alone.
"""

from __future__ import annotations

import os

MAX_BUFFER_MB = "GUACA_MAX_BUFFER_MB"
RASTER_STAGES = "GUACA_RASTER_STAGES"


def max_buffer_mb() -> str | None:
    """The text of GUACA_MAX_BUFFER_MB, or None where it is unset or blank (limits.py parses it)."""
    text = os.environ.get(MAX_BUFFER_MB)
    return text if text is not None and text.strip() else None


def raster_stages() -> bool:
    """Whether GUACA_RASTER_STAGES asks for the compute rasterizer's per-stage GPU times."""
    return os.environ.get(RASTER_STAGES, "") not in ("", "0")
