"""Buffers the GPU reads or writes per fragment, kept out of the CPU's way.

NVIDIA's OpenGL driver places a buffer object by how the CPU uses it. A storage buffer that the
CPU wrote before and read after every frame (the A-buffer's counters) ended up where every
shader atomic on it cost ~35 ns: on the H100 a 1024² full-screen layer took 70 ms of geometry
against 1.3 ms once the same counters were reset and read only through GPU-side copies
(docs/performance.md has the experiment; `GUACA_DIRECT_CPU_ACCESS=1` reproduces the old access
pattern). So buffers that shaders touch are written and read by the CPU only through small
staging buffers and glCopyBufferSubData.
"""

from __future__ import annotations

import os

import numpy as np


def direct_cpu_access() -> bool:
    """True when the old pattern (CPU writes/reads the shader's own buffer) is asked for, to measure it."""
    return os.environ.get("GUACA_DIRECT_CPU_ACCESS", "") not in ("", "0")


class CounterBlock:
    """uint32 counters that only shaders update: reset by a GPU copy, read back through a staging copy."""

    def __init__(self, ctx, names: tuple[str, ...]):
        self.ctx = ctx
        self.names = tuple(names)
        size = 4 * len(self.names)
        self.buffer = ctx.buffer(reserve=size)  # the shaders' copy: never mapped, written or read by the CPU
        self._initial = ctx.buffer(reserve=size)  # reset values, copied over `buffer` on the GPU
        self._staging = ctx.buffer(reserve=size)  # read-back copy
        self._late = ctx.buffer(reserve=size)  # copy read one frame later (frame loops without read-back)
        self._late_tag: object = None
        self._late_valid = False
        self._initial_values: tuple[int, ...] | None = None

    def reset(self, **values: int) -> None:
        """Set every counter to 0, or to the value given by name, before the GPU uses them."""
        words = tuple(int(values.pop(n, 0)) for n in self.names)
        if values:
            raise KeyError(f"unknown counters: {', '.join(values)}")
        if direct_cpu_access():
            self.buffer.write(np.array(words, dtype=np.uint32).tobytes())
            return
        if words != self._initial_values:
            self._initial.write(np.array(words, dtype=np.uint32).tobytes())
            self._initial_values = words
        self.ctx.copy_buffer(self.buffer, self._initial)

    def read(self) -> dict[str, int]:
        """The counters by name (waits for the GPU work that updates them); an older stage() is dropped."""
        self._late_valid = False  # a frame read now: what was set aside before it is older than that
        src = self.buffer
        if not direct_cpu_access():
            self.ctx.copy_buffer(self._staging, self.buffer)
            src = self._staging
        return dict(zip(self.names, np.frombuffer(src.read(), dtype=np.uint32).tolist()))

    def stage(self, tag: object = None) -> None:
        """Copy the counters aside on the GPU, to be read by staged() a frame later without waiting now."""
        self.ctx.copy_buffer(self._late, self.buffer)
        self._late_tag, self._late_valid = tag, True

    def staged(self) -> tuple[dict[str, int], object] | None:
        """The counters of the last stage() call and its tag (by then finished on the GPU); None if none."""
        if not self._late_valid:
            return None
        self._late_valid = False
        return dict(zip(self.names, np.frombuffer(self._late.read(), dtype=np.uint32).tolist())), self._late_tag

    def latest(self, late: bool) -> tuple[dict[str, int], object, bool]:
        """(counters, stage() tag, whether staged): with `late` (a frame loop without read-back) the
        counters stage() set aside a frame ago where there are some, which needs no wait; else this
        frame's (waits for the GPU work that updates them)."""
        staged = self.staged() if late else None
        if staged is not None:
            return staged[0], staged[1], True
        return self.read(), None, False

    def bind(self, binding: int) -> None:
        """Bind as the shader storage block at `binding`."""
        self.buffer.bind_to_storage_buffer(binding)

    def release(self) -> None:
        """Free the buffers."""
        for b in (self.buffer, self._initial, self._staging, self._late):
            b.release()


class UploadBuffer:
    """A storage buffer the CPU fills each frame through a staging copy (shaders read a GPU-placed buffer)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.buffer = None
        self._staging = None

    def upload(self, data: bytes, min_size: int = 64) -> None:
        """Replace the contents with `data` (the buffer grows when needed, never shrinks below the data)."""
        size = max(len(data), min_size)
        if self.buffer is None or self.buffer.size < size:
            self.release()
            self.buffer = self.ctx.buffer(reserve=size)
            self._staging = self.ctx.buffer(reserve=size, dynamic=True)
        if not data:
            return
        if direct_cpu_access():
            self.buffer.write(data)
            return
        self._staging.write(data)
        self.ctx.copy_buffer(self.buffer, self._staging, size=len(data))

    def bind(self, binding: int) -> None:
        """Bind as the shader storage block at `binding`."""
        self.buffer.bind_to_storage_buffer(binding)

    def release(self) -> None:
        """Free both buffers."""
        for b in (self.buffer, self._staging):
            if b is not None:
                b.release()
        self.buffer = self._staging = None


class StagedReader:
    """Reads a few bytes of a shader's buffer through a GPU copy into a small staging buffer."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._staging = None

    def read(self, buffer, size: int, offset: int = 0) -> bytes:
        """`size` bytes of `buffer` from `offset` (waits for the GPU work that writes them)."""
        if direct_cpu_access():
            return buffer.read(size=size, offset=offset)
        if self._staging is None or self._staging.size < size:
            self.release()
            self._staging = self.ctx.buffer(reserve=max(size, 16))
        self.ctx.copy_buffer(self._staging, buffer, size=size, read_offset=offset)
        return self._staging.read(size=size)

    def release(self) -> None:
        """Free the staging buffer."""
        if self._staging is not None:
            self._staging.release()
            self._staging = None
