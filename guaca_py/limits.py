"""Device limits and the one storage rule every transparency method follows.

The rule: a buffer that shaders index holds at most `DeviceLimits.max_buffer_bytes`, which is the
smallest of

* the range a shader can index (`index_limit_bytes`): 2 GiB - 1 (`INDEX_LIMIT_BYTES`) where byte
  offsets are signed 32-bit ints, as llvmpipe computes them (measured: a 2.00 GB node pool renders,
  2.18 GB segfaults inside the shader); 3 GiB on NVIDIA (`NVIDIA_INDEX_LIMIT_BYTES`), which reports
  a 2 GiB - 1 GL_MAX_SHADER_STORAGE_BLOCK_SIZE but indexes a bound 3 GiB buffer to its end
  (measured on the H100: stores at its last 1 MiB read back; a 5 GiB buffer's did not). Every
  method indexes its buffers by 32-bit word or record (the A-buffer's node n at word 8n), so 3 GiB
  stays below 2^31 words and a pool of 40-byte nodes grows from 53M to 80M nodes;
* half of the memory the device reports free at context creation (`GL_NVX_gpu_memory_info` on
  NVIDIA; `MemAvailable` of the host on software rasterizers, whose buffers live in host memory);
* `GUACA_MAX_BUFFER_MB` from the environment, where set (to test the degradation path, or to
  leave memory to the host application).

`GL_MAX_SHADER_STORAGE_BLOCK_SIZE` is recorded and shown by `guaca info` but is not a cap: Mesa
advertises a fixed 128 MiB and addresses the whole bound range (measured on llvmpipe: a 190 MB
presort_lf pool, and 147 MB of dfb, sbuffer and paged_ll fragments, 4.59M fragments, give the same
image as presort_lf), so one rule holds for all methods.
Storage that the rule caps degrades like any full pool: fragments are dropped, counted and warned.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

import numpy as np

from . import env
from .errors import LimitError
from .gl_state import raw_gl

INDEX_LIMIT_BYTES = 2**31 - 1
NVIDIA_INDEX_LIMIT_BYTES = 3 * 2**30
MEMORY_SHARE = 0.5  # of the memory reported free: the rest stays with the driver and the host application
ENV_CAP = env.MAX_BUFFER_MB
_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX = 0x9049  # KiB
_MIB = 1024 * 1024
# G-buffer (3 half-float RGBA + depth), linear colour and two post targets (float RGBA), A-buffer
# heads and saturation depth, light grid: an upper estimate of what a frame holds per pixel
FRAME_BYTES_PER_PIXEL = 96


@dataclass(frozen=True)
class DeviceLimits:
    """Sizes the device can hold, queried once at context creation."""

    max_buffer_bytes: int  # largest buffer a shader may index (the rule above)
    binding: str  # which limit sets max_buffer_bytes, for warnings
    reported_block_bytes: int  # GL_MAX_SHADER_STORAGE_BLOCK_SIZE as the driver reports it
    available_bytes: int | None  # memory free at context creation, where reported
    max_framebuffer: tuple[int, int]  # largest render target
    texture_bytes_per_pixel: int = 16  # the widest per-pixel target (rgba32f)

    def elements(self, element_bytes: int, fixed_bytes: int = 0) -> int:
        """How many elements of `element_bytes` fit in one buffer after `fixed_bytes` of other content."""
        return max(0, (self.max_buffer_bytes - fixed_bytes) // max(1, element_bytes))

    def describe(self) -> str:
        """The cap in words: size and what sets it."""
        return f"{self.max_buffer_bytes / _MIB:.4g} MiB per buffer, {self.binding}"


def _nvx_available_bytes(ext: set) -> int | None:
    """Free video memory from GL_NVX_gpu_memory_info through the current context, or None."""
    gl = raw_gl() if "GL_NVX_gpu_memory_info" in ext else None
    if gl is None:
        return None
    kib = gl.get(_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX)[0]
    return kib * 1024 if kib > 0 else None


def _host_available_bytes() -> int | None:
    """MemAvailable of the host (Linux), or None where it cannot be read."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def env_cap_bytes() -> int | None:
    """The cap set by GUACA_MAX_BUFFER_MB, or None; a bad value is a LimitError naming the variable."""
    text = env.max_buffer_mb()
    if text is None:
        return None
    try:
        mb = float(text)
    except ValueError:
        mb = -1.0
    if not mb > 0 or mb != mb or mb == float("inf"):
        raise LimitError(f"{ENV_CAP}={text!r} is not a positive number of MB", key=ENV_CAP, hint=f"e.g. {ENV_CAP}=64")
    return max(4096, int(mb * _MIB))


def index_limit_bytes(vendor: str, software: bool) -> tuple[int, str]:
    """The largest buffer a shader indexes on a device of GL vendor `vendor`, and why (the rule above)."""
    if not software and "nvidia" in vendor.lower():
        return NVIDIA_INDEX_LIMIT_BYTES, "the range NVIDIA's shaders index (measured: 3 GiB)"
    return INDEX_LIMIT_BYTES, "the 32-bit offsets shaders index buffers with"


def query_limits(ctx, software: bool) -> DeviceLimits:
    """Read the device's limits (once, at context creation) and apply the storage rule."""
    info = ctx.info
    ext = set(ctx.extensions)
    available = _nvx_available_bytes(ext)
    source = "half the free video memory"
    if available is None and software:
        available, source = _host_available_bytes(), "half the host's available memory"
    candidates = [index_limit_bytes(str(info.get("GL_VENDOR", "")), software)]
    if available:
        candidates.append((int(available * MEMORY_SHARE), source))
    env = env_cap_bytes()
    if env is not None:
        candidates.append((env, f"lowered by {ENV_CAP}"))
    cap, why = min(candidates)
    fb = (
        int(info.get("GL_MAX_FRAMEBUFFER_WIDTH", 16384)),
        int(info.get("GL_MAX_FRAMEBUFFER_HEIGHT", 16384)),
    )
    tex = int(info.get("GL_MAX_TEXTURE_SIZE", 16384))
    return DeviceLimits(
        max_buffer_bytes=int(cap),
        binding=why,
        reported_block_bytes=int(info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 0)),
        available_bytes=available,
        max_framebuffer=(min(fb[0], tex), min(fb[1], tex)),
    )


def _size(value, name: str, what: str | None) -> int:
    """`value` as a positive Python int (numpy integers too), else a LimitError naming `what` or the argument."""
    try:
        v = operator.index(value)  # any integer type, never a float, a string or an array
    except TypeError:
        v = None
    if v is None or isinstance(value, (bool, np.bool_)) or v <= 0:
        reason = f"must be a positive integer, got {value!r}"
        raise LimitError(reason if what is None else f"{name} {reason}", key=what or name, hint="e.g. 512")
    return v


def check_resolution(
    limits: DeviceLimits | None, width, height, what: str | None = None, supersample: int = 1
) -> tuple[int, int]:
    """Validate a frame size against the device: positive integers, within render-target and buffer limits.

    Errors name `what` (a command-line option, a pipeline key) where given, else the arguments
    `width` and `height` of the Python call. With `supersample` K > 1 the frame renders at K times
    the width and height: that size is held to the same limits, and its error names antialiasing.supersample.
    """
    width, height = _size(width, "width", what), _size(height, "height", what)
    what = what or "width/height"
    if limits is None:
        return width, height
    problem = size_problem(limits, width, height)
    if problem:
        raise LimitError(f"{width}x{height} {problem[0]}", key=what, hint=problem[1])
    problem = size_problem(limits, supersample * width, supersample * height) if supersample > 1 else None
    if problem:  # every target and per-pixel buffer before the composite has the rendered size
        fits = [k for k in range(supersample - 1, 1, -1) if not size_problem(limits, k * width, k * height)]
        lower = f"use antialiasing.supersample {fits[0]}" if fits else "turn antialiasing.supersample off (1)"
        raise LimitError(
            f"{width}x{height} supersampled {supersample}x renders {supersample * width}x{supersample * height}, "
            f"which {problem[0]}",
            key="antialiasing.supersample",
            hint=f"{lower}, or render a smaller image",
        )
    return width, height


def size_problem(limits: DeviceLimits, width: int, height: int) -> tuple[str, str] | None:
    """(what a frame of `width` x `height` exceeds, what to do instead), or None when the device holds it."""
    mw, mh = limits.max_framebuffer
    if width > mw or height > mh:
        return f"exceeds the device's largest render target {mw}x{mh}", "render at most that size (tile larger images)"
    per_target = width * height * limits.texture_bytes_per_pixel
    if per_target > limits.max_buffer_bytes:
        most = int((limits.max_buffer_bytes / limits.texture_bytes_per_pixel) ** 0.5)
        return (
            f"needs {per_target / _MIB:.0f} MiB per float render target; the device holds {limits.describe()}",
            f"render at most about {most}x{most} pixels",
        )
    frame_bytes = width * height * FRAME_BYTES_PER_PIXEL
    if limits.available_bytes and frame_bytes > limits.available_bytes * MEMORY_SHARE:
        return (
            f"needs about {frame_bytes / _MIB:.0f} MiB of render targets; the device reports "
            f"{limits.available_bytes / _MIB:.0f} MiB free",
            "render a smaller image",
        )
    return None


def pool_node_limit(limits: DeviceLimits | None, head_words: int, link_bytes: int, payload_bytes: int) -> int:
    """Most nodes of a linked-list pool: payloads fit one buffer, heads + links another, indices 32 bits."""
    if limits is None:
        return 2**32 - 1
    return max(
        2,
        min(limits.elements(payload_bytes), limits.elements(link_bytes, head_words * link_bytes), 2**32 - 1),
    )


def require_bytes(limits: DeviceLimits | None, nbytes: int, what: str, hint: str) -> None:
    """A per-pixel buffer that cannot shrink (no overflow path) must fit the storage rule, else a LimitError."""
    if limits is not None and nbytes > limits.max_buffer_bytes:
        raise LimitError(
            f"needs a {nbytes / _MIB:.4g} MiB buffer; the device holds {limits.describe()}", key=what, hint=hint
        )
