"""Raw glEnable/glDisable for GL state that moderngl has no API for (e.g. NV conservative rasterization)."""

from __future__ import annotations

from .host_state import RawGLFunctions, raw_functions_or_none

GL_CONSERVATIVE_RASTERIZATION_NV = 0x9346


class RawGL:
    """glEnable / glDisable / glIsEnabled / glGetError on the current context (host_state's ctypes entry points)."""

    def __init__(self, gl: RawGLFunctions):
        self._gl = gl
        self.source = gl.source

    def enable(self, cap: int) -> None:
        """glEnable(cap)."""
        self._gl.glEnable(cap)

    def disable(self, cap: int) -> None:
        """glDisable(cap)."""
        self._gl.glDisable(cap)

    def is_enabled(self, cap: int) -> bool:
        """glIsEnabled(cap)."""
        return bool(self._gl.glIsEnabled(cap))

    def clear_errors(self) -> list[int]:
        """Drain glGetError; returns the error codes that were pending."""
        return self._gl.drain_errors()

    def try_enable(self, cap: int) -> bool:
        """Enable `cap` and confirm the context took it (False, state unchanged, when it did not)."""
        self.clear_errors()
        self.enable(cap)
        ok = not self.clear_errors() and self.is_enabled(cap)
        if not ok:
            self.disable(cap)
            self.clear_errors()
        return ok


def raw_gl() -> RawGL | None:
    """Raw GL state calls, or None when no GL library can be loaded."""
    gl = raw_functions_or_none()
    return RawGL(gl) if gl is not None else None


__all__ = ["GL_CONSERVATIVE_RASTERIZATION_NV", "RawGL", "raw_gl"]
