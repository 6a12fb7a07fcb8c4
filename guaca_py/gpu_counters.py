"""Buffers the GPU reads or writes per fragment, kept out of the CPU's way.

NVIDIA's OpenGL driver places a buffer object by how the CPU uses it. A storage buffer that the
CPU wrote before and read after every frame (the A-buffer's counters) ended up where every
shader atomic on it cost ~35 ns: on the H100 a 1024² full-screen layer took 70 ms of geometry
against 1.3 ms once the same counters were reset and read only through GPU-side copies
(docs/performance.md has the experiment, docs/decisions.md its record). So buffers that shaders touch are written and read by the CPU only through small
staging buffers and glCopyBufferSubData.

Counters a frame loop reads a frame late go through `FencedCopies`: a GPU copy into a persistently
mapped buffer and a fence after it, so the CPU reads them without asking the driver for a
read-back. glGetBufferSubData on the H100 waited for every command queued before it, the current
frame's geometry included, so a loop without read-back ran its frames' GPU and CPU work one after
the other (hairball_v1: 8.8 ms a frame where the GPU needs 4.7).
"""

from __future__ import annotations

import ctypes
from collections import deque

import numpy as np

from .gl_state import raw_gl

_MAP_READ, _MAP_PERSISTENT, _MAP_COHERENT, _CLIENT_STORAGE = 0x1, 0x40, 0x80, 0x200
_SYNC_GPU_COMMANDS_COMPLETE, _SYNC_FLUSH_COMMANDS = 0x9117, 0x1
_ALREADY_SIGNALED, _CONDITION_SATISFIED = 0x911A, 0x911C
_WAIT_FOREVER = 0xFFFFFFFFFFFFFFFF


class FencedCopies:
    """Copies of a small buffer, each read by the CPU once the GPU has finished it, without a driver read-back.

    `slots` copies may wait at once (a frame loop's CPU runs at most that many frames ahead of
    the GPU); each lives in a persistently mapped, CPU-coherent buffer with a fence after its copy.
    """

    def __init__(self, gl, size: int, slots: int = 3):
        self._gl, self.size = gl, size
        names = (ctypes.c_uint * slots)()
        gl.glCreateBuffers(slots, names)
        self._names = list(names)
        flags = _MAP_READ | _MAP_PERSISTENT | _MAP_COHERENT
        self._maps = []
        self._free = list(range(slots))
        self._pending: deque = deque()  # (slot, fence, tag), oldest first
        for name in self._names:
            gl.glNamedBufferStorage(name, size, None, flags | _CLIENT_STORAGE)
            self._maps.append(gl.glMapNamedBufferRange(name, 0, size, flags))
        if not all(self._maps):
            self.release()
            raise OSError("the driver did not map a persistent read-back buffer")

    def copy(self, buffer, tag: object = None) -> None:
        """Queue a copy of `buffer`'s first `size` bytes (a moderngl buffer) with its tag; the oldest waiting copy is dropped when all slots wait."""
        if not self._free:
            self._drop_oldest()
        slot = self._free.pop()
        self._gl.glCopyNamedBufferSubData(buffer.glo, self._names[slot], 0, 0, self.size)
        self._pending.append((slot, self._gl.glFenceSync(_SYNC_GPU_COMMANDS_COMPLETE, 0), tag))

    def _done(self, fence, wait: bool) -> bool:
        result = self._gl.glClientWaitSync(fence, _SYNC_FLUSH_COMMANDS, _WAIT_FOREVER if wait else 0)
        return result in (_ALREADY_SIGNALED, _CONDITION_SATISFIED)

    def _drop_oldest(self) -> tuple[int, object]:
        slot, fence, tag = self._pending.popleft()
        self._gl.glDeleteSync(fence)
        self._free.append(slot)
        return slot, tag

    def newest(self) -> tuple[bytes, object] | None:
        """(bytes, tag) of the newest copy the GPU has finished, dropping older ones; None when none waits.

        When none has finished yet, waits for the oldest (only for it: later frames' commands
        keep running).
        """
        if not self._pending:
            return None
        done = [i for i, (_, fence, _) in enumerate(self._pending) if self._done(fence, wait=False)]
        if not done:
            self._done(self._pending[0][1], wait=True)
            done = [0]
        for _ in range(done[-1]):
            self._drop_oldest()
        slot, tag = self._drop_oldest()
        return ctypes.string_at(self._maps[slot], self.size), tag

    def discard(self) -> None:
        """Forget every waiting copy."""
        while self._pending:
            self._drop_oldest()

    def release(self) -> None:
        """Free the buffers and fences (unmapped with them)."""
        self.discard()
        names = (ctypes.c_uint * len(self._names))(*self._names)
        self._gl.glDeleteBuffers(len(self._names), names)
        self._names, self._maps = [], []


class _BufferCopies:
    """FencedCopies' interface over one plain buffer read back by the driver (its read waits for the GPU)."""

    def __init__(self, ctx, size: int):
        self.ctx, self._buffer = ctx, ctx.buffer(reserve=size)
        self._tag: object = None
        self._valid = False

    def copy(self, buffer, tag: object = None) -> None:
        """Copy `buffer` over the one held copy."""
        self.ctx.copy_buffer(self._buffer, buffer)
        self._tag, self._valid = tag, True

    def newest(self) -> tuple[bytes, object] | None:
        """(bytes, tag) of the last copy not read yet; None when there is none."""
        if not self._valid:
            return None
        self._valid = False
        return self._buffer.read(), self._tag

    def discard(self) -> None:
        """Forget the held copy."""
        self._valid = False

    def release(self) -> None:
        """Free the buffer."""
        self._buffer.release()


def _fenced_or_none(size: int) -> FencedCopies | None:
    """FencedCopies of `size` bytes on the current context, or None where it cannot have them."""
    gl = raw_gl()
    if gl is None:
        return None
    try:
        return FencedCopies(gl, size)
    except OSError:
        return None


class CounterBlock:
    """uint32 counters that only shaders update: reset by a GPU copy, read back through a staging copy.

    Copies set aside to be read a frame late are kept per view (`view`: the frame's index among the
    views of one render_views() call), so each view reads its own counters of the previous call.
    """

    def __init__(self, ctx, names: tuple[str, ...]):
        self.ctx = ctx
        self.names = tuple(names)
        self._size = size = 4 * len(self.names)
        self.buffer = ctx.buffer(reserve=size)  # the shaders' copy: never mapped, written or read by the CPU
        self._initial = ctx.buffer(reserve=size)  # reset values, copied over `buffer` on the GPU
        self._staging = ctx.buffer(reserve=size)  # read-back copy
        # per view: copies read a frame later (frame loops without read-back), made on the first stage()
        self._late: dict[int, FencedCopies | _BufferCopies] = {}
        self._initial_values: tuple[int, ...] | None = None
        self._zeros = (0,) * len(self.names)

    def _copies(self, view: int) -> FencedCopies | _BufferCopies:
        """View `view`'s late copies; a plain buffer read where no raw GL entry points load or the driver maps
        no persistent buffer."""
        copies = self._late.get(view)
        if copies is None:
            copies = self._late[view] = _fenced_or_none(self._size) or _BufferCopies(self.ctx, self._size)
        return copies

    def reset(self, **values: int) -> None:
        """Set every counter to 0, or to the value given by name, before the GPU uses them."""
        if values:
            words = tuple(int(values.pop(n, 0)) for n in self.names)
            if values:
                raise KeyError(f"unknown counters: {', '.join(values)}")
        else:  # every counter 0: the common case, once a frame per block
            words = self._zeros
        if words != self._initial_values:
            self._initial.write(np.array(words, dtype=np.uint32).tobytes())
            self._initial_values = words
        self.ctx.copy_buffer(self.buffer, self._initial)

    def read(self, view: int | None = None) -> dict[str, int]:
        """The counters by name (waits for the GPU work that updates them).

        What stage() set aside before is older than this frame and dropped: view `view`'s where
        given (a loop without read-back that has nothing staged for that view yet; the other
        views' copies stay theirs), else every view's.
        """
        for v, copies in self._late.items():
            if view is None or v == view:
                copies.discard()
        self.ctx.copy_buffer(self._staging, self.buffer)
        return dict(zip(self.names, np.frombuffer(self._staging.read(), dtype=np.uint32).tolist()))

    def stage(self, tag: object = None, view: int = 0) -> None:
        """Copy the counters aside on the GPU, to be read by staged(view) a frame later without waiting now."""
        self._copies(view).copy(self.buffer, tag)

    def staged(self, view: int = 0) -> tuple[dict[str, int], object] | None:
        """View `view`'s counters of the newest stage() the GPU has finished and its tag; None if none was staged."""
        copies = self._late.get(view)
        got = copies.newest() if copies is not None else None
        if got is None:
            return None
        return dict(zip(self.names, np.frombuffer(got[0], dtype=np.uint32).tolist())), got[1]

    def latest(self, late: bool, view: int = 0) -> tuple[dict[str, int], object, bool]:
        """(counters, stage() tag, whether staged): with `late` (a frame loop without read-back) the
        counters stage() set aside for view `view` a frame ago where there are some, which needs no
        wait; else this frame's (waits for the GPU work that updates them)."""
        staged = self.staged(view) if late else None
        if staged is not None:
            return staged[0], staged[1], True
        return self.read(view if late else None), None, False

    def bind(self, binding: int) -> None:
        """Bind as the shader storage block at `binding`."""
        self.buffer.bind_to_storage_buffer(binding)

    def release(self) -> None:
        """Free the buffers."""
        for b in (self.buffer, self._initial, self._staging, *self._late.values()):
            b.release()
        self._late.clear()


class UploadBuffer:
    """A storage buffer the CPU fills each frame through a staging copy (shaders read a GPU-placed buffer)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.buffer = None
        self._staging = None
        self._held = b""  # the bytes the buffer holds from the last upload

    def upload(self, data: bytes, min_size: int = 64) -> None:
        """Replace the contents with `data` (the buffer grows when needed, never shrinks below the data).

        The same bytes as the last upload are not sent again: shaders only read this buffer.
        """
        size = max(len(data), min_size)
        if self.buffer is None or self.buffer.size < size:
            self.release()
            self.buffer = self.ctx.buffer(reserve=size)
            self._staging = self.ctx.buffer(reserve=size, dynamic=True)
        if not data or data == self._held:
            return
        self._held = data
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
        self._held = b""


class StagedReader:
    """Reads a few bytes of a shader's buffer through a GPU copy into a small staging buffer."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._staging = None

    def read(self, buffer, size: int, offset: int = 0) -> bytes:
        """`size` bytes of `buffer` from `offset` (waits for the GPU work that writes them)."""
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
