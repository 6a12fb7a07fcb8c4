"""Python values in the layout GL uniforms take."""

from __future__ import annotations

import numpy as np


def mat_bytes(m: np.ndarray) -> bytes:
    """A float64 row-major numpy matrix as the column-major float32 bytes GL expects."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()
