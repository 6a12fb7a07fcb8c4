"""In-memory texture images (e.g. embedded in glTF files), identified by content."""

from __future__ import annotations

import hashlib

import numpy as np


class TextureImage:
    """An RGBA8 image held in memory; usable wherever a sampler2D uniform takes a texture path.

    Treat the pixels as immutable once rendered: GPU copies are shared by content digest.
    """

    def __init__(self, pixels: np.ndarray, name: str = "image"):
        px = np.asarray(pixels)
        if px.ndim == 2:
            px = px[:, :, None]
        if px.ndim != 3 or px.shape[2] not in (1, 2, 3, 4) or px.shape[0] < 1 or px.shape[1] < 1:
            raise ValueError(f"texture image must be (H, W[, 1-4]) pixels, got shape {np.shape(pixels)}")
        if px.dtype != np.uint8:
            px = np.clip(np.rint(np.asarray(px, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
        if px.shape[2] < 4:  # grey, grey+alpha, rgb -> rgba
            grey = px[:, :, :1]
            rgb = px[:, :, :3] if px.shape[2] >= 3 else np.repeat(grey, 3, axis=2)
            alpha = px[:, :, 3:4] if px.shape[2] == 4 else (px[:, :, 1:2] if px.shape[2] == 2 else None)
            alpha = np.full_like(grey, 255) if alpha is None else alpha
            px = np.concatenate([rgb, alpha], axis=2)
        self.pixels = np.ascontiguousarray(px)
        self.name = name
        self.digest = hashlib.blake2b(
            self.pixels.tobytes() + repr(self.pixels.shape).encode(), digest_size=16
        ).hexdigest()

    @property
    def size(self) -> tuple[int, int]:
        """(width, height)."""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])

    def __repr__(self) -> str:
        return f"TextureImage({self.name!r}, {self.size[0]}x{self.size[1]}, {self.digest[:8]})"
