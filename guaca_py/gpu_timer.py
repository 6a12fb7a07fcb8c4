"""GPU queries (timer, samples passed) that can be deleted: moderngl's Query has no release, so each renderer left its names behind."""

from __future__ import annotations

import ctypes

from .gl_state import raw_gl

GL_TIME_ELAPSED = 0x88BF
GL_SAMPLES_PASSED = 0x8914
GL_TIMESTAMP = 0x8E28
GL_QUERY_RESULT = 0x8866


def _new_query(gl) -> int:
    """A fresh GL query name."""
    name = ctypes.c_uint(0)
    gl.glGenQueries(1, ctypes.byref(name))
    return name.value


def _query_result(gl, name: int) -> int:
    """The query's 64-bit result (waits for it)."""
    out = ctypes.c_uint64(0)
    gl.glGetQueryObjectui64v(name, GL_QUERY_RESULT, ctypes.byref(out))
    return int(out.value)


def _delete_query(gl, name: int) -> None:
    """Delete one query name."""
    gl.glDeleteQueries(1, ctypes.byref(ctypes.c_uint(name)))


class _Query:
    """A query of `target` around a block (`with q: ...`), read with `result` (waits), freed with `release()`."""

    target = GL_TIME_ELAPSED

    def __init__(self, ctx):
        self._gl = raw_gl()
        self._fallback = None
        if self._gl is None:  # no raw entry points: moderngl's query (its name stays until exit)
            self._fallback = ctx.query(time=self.target == GL_TIME_ELAPSED, samples=self.target == GL_SAMPLES_PASSED)
            return
        self.name = _new_query(self._gl)

    def __enter__(self):
        if self._fallback is not None:
            return self._fallback.__enter__()
        self._gl.glBeginQuery(self.target, self.name)
        return self

    def __exit__(self, *exc):
        if self._fallback is not None:
            return self._fallback.__exit__(*exc)
        self._gl.glEndQuery(self.target)
        return False

    @property
    def result(self) -> int:
        """The query's value (waits for the GPU to finish the block)."""
        if self._fallback is not None:
            return self._fallback.elapsed if self.target == GL_TIME_ELAPSED else self._fallback.samples
        return _query_result(self._gl, self.name)

    def release(self) -> None:
        """Delete the query object (the context must be current)."""
        if self._gl is not None and self.name:
            _delete_query(self._gl, self.name)
            self.name = 0


class TimerQuery(_Query):
    """GL_TIME_ELAPSED around a block: `elapsed` nanoseconds."""

    target = GL_TIME_ELAPSED

    @property
    def elapsed(self) -> int:
        """Nanoseconds the block took on the GPU (waits for the result)."""
        return self.result


class SamplesQuery(_Query):
    """GL_SAMPLES_PASSED around a block: `samples` that passed the depth test."""

    target = GL_SAMPLES_PASSED

    @property
    def samples(self) -> int:
        """Samples that passed (waits for the result)."""
        return self.result


class Timestamps:
    """GPU timestamps at marked points of the command stream (glQueryCounter: allowed inside a timer query).

    Reading them waits for the GPU: for profiling only (GUACA_RASTER_STAGES=1), never on the hot path.
    """

    def __init__(self):
        self._gl = raw_gl()
        self._free: list[int] = []
        self._marks: list[tuple[str, int]] = []

    def mark(self, label: str) -> None:
        """Record the GPU time when the commands issued so far have run, under `label`."""
        if self._gl is None:
            return
        name = self._free.pop() if self._free else _new_query(self._gl)
        self._gl.glQueryCounter(name, GL_TIMESTAMP)
        self._marks.append((label, name))

    def spans_ms(self) -> dict[str, float]:
        """Milliseconds from each mark to the next, summed by the later mark's label; clears the marks."""
        times = [(label, _query_result(self._gl, name)) for label, name in self._marks]
        self._free += [name for _, name in self._marks]
        self._marks = []
        spans: dict[str, float] = {}
        for (_, t0), (label, t1) in zip(times, times[1:]):
            spans[label] = spans.get(label, 0.0) + (t1 - t0) / 1e6
        return spans

    def release(self) -> None:
        """Delete the query objects (the context must be current)."""
        if self._gl is not None:
            for name in self._free + [n for _, n in self._marks]:
                _delete_query(self._gl, name)
        self._free, self._marks = [], []
