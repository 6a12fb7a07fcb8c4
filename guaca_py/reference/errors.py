"""Errors of linear frames against a reference, in 1/255 of the output range (and FLIP where installed)."""

from __future__ import annotations

from concurrent.futures import Executor

import numpy as np


def rmse_255(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float:
    """RMSE in 1/255 of two linear images clipped to [0, 1], over `mask` (all pixels if None)."""
    d = (np.clip(np.asarray(image, np.float64), 0, 1) - np.clip(reference, 0, 1)) * 255.0
    if mask is not None:
        if not mask.any():
            return float("nan")
        d = d[mask]
    return float(np.sqrt(np.mean(d**2)))


def srgb(linear: np.ndarray) -> np.ndarray:
    """sRGB encoding of linear values clipped to [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def flip(image: np.ndarray, reference: np.ndarray) -> float | None:
    """Mean LDR-FLIP of two linear images (sRGB-encoded for FLIP), or None without `flip-evaluator`."""
    try:
        import flip_evaluator
    except ImportError:
        return None
    ref = srgb(reference).astype(np.float32)
    test = srgb(image).astype(np.float32)
    _, mean, _ = flip_evaluator.evaluate(ref, test, "LDR", applyMagma=False)
    return float(mean)


def rmse_max_255(image: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """RMSE and largest absolute error in 1/255 of two linear images clipped to [0, 1]."""
    d = (np.clip(image, 0, 1) - np.clip(reference, 0, 1)) * 255.0
    return float(np.sqrt(np.mean(d**2))), float(np.abs(d).max())


def frame_errors(image: np.ndarray, reference: np.ndarray, edges: np.ndarray, pool: Executor | None = None) -> dict:
    """RMSE, edge RMSE (1/255) and FLIP of a linear frame against a linear reference; FLIP as a future
    where `pool` (a concurrent.futures executor) computes it while the caller renders on."""
    return {
        "rmse_255": rmse_255(image, reference),
        "edge_rmse_255": rmse_255(image, reference, edges),
        "flip": pool.submit(flip, image, reference) if pool is not None else flip(image, reference),
    }
