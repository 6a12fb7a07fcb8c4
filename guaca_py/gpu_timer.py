"""GPU timer queries that can be deleted: moderngl's Query has no release, so each renderer left its names behind."""

from __future__ import annotations

import ctypes

from .host_state import raw_functions_or_none

GL_TIME_ELAPSED = 0x88BF
GL_QUERY_RESULT = 0x8866


class TimerQuery:
    """A GL_TIME_ELAPSED query around a block (`with q: ...`), read with `elapsed` (ns), freed with `release()`."""

    def __init__(self, ctx):
        self._gl = raw_functions_or_none()
        self._fallback = None
        if self._gl is None:  # no raw entry points: moderngl's query (its name stays until exit)
            self._fallback = ctx.query(time=True)
            return
        name = ctypes.c_uint(0)
        self._gl.glGenQueries(1, ctypes.byref(name))
        self.name = name.value

    def __enter__(self):
        if self._fallback is not None:
            return self._fallback.__enter__()
        self._gl.glBeginQuery(GL_TIME_ELAPSED, self.name)
        return self

    def __exit__(self, *exc):
        if self._fallback is not None:
            return self._fallback.__exit__(*exc)
        self._gl.glEndQuery(GL_TIME_ELAPSED)
        return False

    @property
    def elapsed(self) -> int:
        """Nanoseconds the block took on the GPU (waits for the result)."""
        if self._fallback is not None:
            return self._fallback.elapsed
        out = ctypes.c_uint64(0)
        self._gl.glGetQueryObjectui64v(self.name, GL_QUERY_RESULT, ctypes.byref(out))
        return int(out.value)

    def release(self) -> None:
        """Delete the query object (the context must be current)."""
        if self._gl is not None and self.name:
            name = ctypes.c_uint(self.name)
            self._gl.glDeleteQueries(1, ctypes.byref(name))
            self.name = 0
