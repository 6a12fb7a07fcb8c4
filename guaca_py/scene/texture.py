"""In-memory texture images (e.g. embedded in glTF files), identified by content."""

from __future__ import annotations

import hashlib
import io
import os
import struct
import zlib

import numpy as np

from ..errors import ConfigError
from .nodes import ValueConfigError

#: the largest texture side decoded; the header is read first, so a larger image costs no memory
MAX_TEXTURE_SIDE = 16384
#: suffixes of image files a scene's string value names as a texture (formats Pillow decodes)
TEXTURE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".gif", ".tga", ".tif", ".tiff", ".webp")


class TextureImage:
    """An RGBA8 image held in memory; usable wherever a sampler2D uniform takes a texture path.

    Treat the pixels as immutable once rendered: GPU copies are shared by content digest.
    """

    def __init__(self, pixels: np.ndarray, name: str = "image"):
        px = np.asarray(pixels)
        if px.ndim == 2:
            px = px[:, :, None]
        if px.ndim != 3 or px.shape[2] not in (1, 2, 3, 4) or px.shape[0] < 1 or px.shape[1] < 1:
            raise ValueConfigError(
                f"must be (H, W[, 1-4]) pixels, got shape {np.shape(pixels)}", key=f"TextureImage {name!r}"
            )
        if max(px.shape[:2]) > MAX_TEXTURE_SIDE:
            raise ValueConfigError(
                f"is {px.shape[1]}x{px.shape[0]}; the largest texture is {MAX_TEXTURE_SIDE}x{MAX_TEXTURE_SIDE}",
                key=f"TextureImage {name!r}",
                hint="scale the image down",
            )
        if not (np.issubdtype(px.dtype, np.number) or px.dtype == np.bool_):
            raise ValueConfigError(f"must hold numbers, got {px.dtype}", key=f"TextureImage {name!r}")
        if px.dtype == np.uint16:  # 16-bit channels (e.g. a 16-bit PNG read by numpy): scaled, not clipped
            px = np.rint(px.astype(np.float64) * (255.0 / 65535.0)).astype(np.uint8)
        elif px.dtype != np.uint8:  # floats (and other integers) in 0..1
            unit = np.nan_to_num(np.asarray(px, dtype=np.float64), nan=0.0, posinf=1.0, neginf=0.0)
            px = np.clip(np.rint(unit * 255.0), 0, 255).astype(np.uint8)
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


def rgba_pixels(img) -> np.ndarray:
    """A PIL image as (H, W, 4) uint8 RGBA; 16-bit and 32-bit greyscale are scaled to 8 bits, not clipped.

    Pillow's convert("RGBA") clips I;16 values above 255 to white; the top byte is the 8-bit value.
    """
    if img.mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        wide = np.asarray(img, dtype=np.int64)
        top = 65535 if img.mode.startswith("I;16") or wide.max(initial=0) <= 65535 else 2**31 - 1
        grey = np.clip(np.rint(np.clip(wide, 0, top) * (255.0 / top)), 0, 255).astype(np.uint8)
        return np.dstack([grey] * 3 + [np.full_like(grey, 255)])
    if img.mode == "F":
        grey = np.clip(np.rint(np.nan_to_num(np.asarray(img, dtype=np.float64)) * 255.0), 0, 255).astype(np.uint8)
        return np.dstack([grey] * 3 + [np.full_like(grey, 255)])
    return np.asarray(img.convert("RGBA"))


def decode_image(source, name: str, limit: int = MAX_TEXTURE_SIDE, limit_name: str = "the largest read") -> np.ndarray:
    """Decode an image file or bytes into RGBA8 pixels; ValueError (saying why) when it is not a readable image.

    The size is read from the header before any pixel is decoded, so an image that would decode
    past `limit` per side (or past Pillow's decompression-bomb bound, twice MAX_IMAGE_PIXELS) is
    refused without allocating it.
    """
    from PIL import Image

    if isinstance(source, (bytes, bytearray, memoryview)):
        if len(source) == 0:
            raise ValueError(f"texture {name} is empty")
        source = io.BytesIO(bytes(source))
    elif os.path.getsize(source) == 0:
        raise ValueError(f"texture {name} is empty")
    try:
        with Image.open(source) as img:
            w, h = img.size
            if max(w, h) > limit or w < 1 or h < 1:
                raise ValueError(f"texture {name} is {w}x{h}; {limit_name} is {limit}x{limit}")
            img.load()
            return rgba_pixels(img)
    except Image.DecompressionBombError as exc:
        raise ValueError(
            f"texture {name} would decode to too many pixels ({exc}); {limit_name} is {limit}x{limit} "
            f"and {2 * (Image.MAX_IMAGE_PIXELS or 0)} pixels"
        ) from None
    except (OSError, SyntaxError, EOFError, struct.error, zlib.error) as exc:
        raise ValueError(f"texture {name} is not a readable image ({exc or type(exc).__name__})") from None


def read_texture_file(path, limit: int = MAX_TEXTURE_SIDE, limit_name: str = "the largest read") -> np.ndarray:
    """decode_image of a texture file, a ConfigError naming the file where it is not a readable image."""
    try:
        return decode_image(path, str(path), limit, limit_name)
    except ValueError as exc:
        formats = ", ".join(s.lstrip(".").upper() for s in TEXTURE_SUFFIXES)
        raise ConfigError(str(exc), path, hint=f"use an image file ({formats}); scale a larger image down") from None
