"""Raw glEnable/glDisable for GL state that moderngl has no API for (e.g. NV conservative rasterization)."""

from __future__ import annotations

import ctypes
from functools import lru_cache

GL_CONSERVATIVE_RASTERIZATION_NV = 0x9346

# GLVND's libOpenGL dispatches to whatever context is current (EGL or GLX), so it comes first;
# eglGetProcAddress is the last resort for systems without GLVND.
_LIBRARIES = ("libOpenGL.so.0", "libGL.so.1", "libGL.so")
_ENABLE = ctypes.CFUNCTYPE(None, ctypes.c_uint)
_IS_ENABLED = ctypes.CFUNCTYPE(ctypes.c_ubyte, ctypes.c_uint)
_GET_ERROR = ctypes.CFUNCTYPE(ctypes.c_uint)


class RawGL:
    """glEnable / glDisable / glIsEnabled / glGetError on the current context, through ctypes."""

    def __init__(self, enable, disable, is_enabled, get_error, source: str):
        self._enable, self._disable, self._is_enabled, self._get_error = enable, disable, is_enabled, get_error
        self.source = source

    def enable(self, cap: int) -> None:
        """glEnable(cap)."""
        self._enable(cap)

    def disable(self, cap: int) -> None:
        """glDisable(cap)."""
        self._disable(cap)

    def is_enabled(self, cap: int) -> bool:
        """glIsEnabled(cap)."""
        return bool(self._is_enabled(cap))

    def clear_errors(self) -> list[int]:
        """Drain glGetError; returns the error codes that were pending."""
        out = []
        for _ in range(16):
            e = self._get_error()
            if not e:
                break
            out.append(int(e))
        return out

    def try_enable(self, cap: int) -> bool:
        """Enable `cap` and confirm the context took it (False, state unchanged, when it did not)."""
        self.clear_errors()
        self.enable(cap)
        ok = not self.clear_errors() and self.is_enabled(cap)
        if not ok:
            self.disable(cap)
            self.clear_errors()
        return ok


def _from_library(name: str) -> RawGL | None:
    try:
        lib = ctypes.CDLL(name)
        fns = [
            ctypes.cast(getattr(lib, f), ctypes.c_void_p).value
            for f in ("glEnable", "glDisable", "glIsEnabled", "glGetError")
        ]
    except (OSError, AttributeError):
        return None
    if not all(fns):
        return None
    return RawGL(_ENABLE(fns[0]), _ENABLE(fns[1]), _IS_ENABLED(fns[2]), _GET_ERROR(fns[3]), name)


def _from_egl() -> RawGL | None:
    try:
        egl = ctypes.CDLL("libEGL.so.1")
        get = egl.eglGetProcAddress
    except (OSError, AttributeError):
        return None
    get.restype, get.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    fns = [get(f) for f in (b"glEnable", b"glDisable", b"glIsEnabled", b"glGetError")]
    if not all(fns):
        return None
    return RawGL(_ENABLE(fns[0]), _ENABLE(fns[1]), _IS_ENABLED(fns[2]), _GET_ERROR(fns[3]), "eglGetProcAddress")


@lru_cache(maxsize=1)
def raw_gl() -> RawGL | None:
    """The first working set of raw GL entry points, or None when no GL library can be loaded."""
    for name in _LIBRARIES:
        gl = _from_library(name)
        if gl is not None:
            return gl
    return _from_egl()


__all__ = ["GL_CONSERVATIVE_RASTERIZATION_NV", "RawGL", "raw_gl"]
