"""GPU exclusive prefix sum (multi-level block scan) and buffer fill, as compute shaders."""

from __future__ import annotations

import math

from .shaders.slots import Buffer

MAX_GROUPS_X = 65535  # guaranteed minimum of GL_MAX_COMPUTE_WORK_GROUP_COUNT per dimension


def dispatch_grid(groups: int) -> tuple[int, int, int]:
    """A 2D work-group grid with at least `groups` groups (shaders skip the padding ones)."""
    gx = max(1, min(groups, MAX_GROUPS_X))
    return gx, max(1, math.ceil(groups / gx)), 1


class GpuFill:
    """Sets the first n uint32 words of a buffer to a value on the GPU."""

    def __init__(self, shaders):
        self.shaders = shaders

    def run(self, buffer, n: int, value: int = 0) -> None:
        """Fill `buffer[0:n]` with `value` (caller issues the memory barrier before use)."""
        if n <= 0:
            return
        prog = self.shaders.compute("counted/fill.comp.j2")
        buffer.bind_to_storage_buffer(Buffer.FILL_TARGET)
        prog["gua_n"] = n
        prog["gua_value"] = value
        prog.run(*dispatch_grid(math.ceil(n / 256)))


class PrefixSum:
    """Exclusive scan of uint32 values in an SSBO: out[i] = in[0] + ... + in[i-1] for i in 0..n.

    One level scans blocks of THREADS*ITEMS values and writes each block's total to an auxiliary
    buffer; that buffer is scanned the same way (recursively, in place) and added back. out[n]
    receives the total, so `out` must hold n + 1 words. Any n >= 0 works; sizes need not be
    powers of two.
    """

    THREADS = 256
    ITEMS = 4
    BLOCK = THREADS * ITEMS

    def __init__(self, ctx, shaders):
        self.ctx = ctx
        self.shaders = shaders
        self._aux: list = []  # block-sum buffers, one per level below the first

    def _vars(self) -> dict:
        return {"threads": self.THREADS, "items": self.ITEMS}

    def _aux_buffer(self, level: int, words: int):
        while len(self._aux) <= level:
            self._aux.append(None)
        buf = self._aux[level]
        if buf is None or buf.size < words * 4:
            if buf is not None:
                buf.release()
            buf = self._aux[level] = self.ctx.buffer(reserve=max(words, 1) * 4)
        return buf

    def run(self, src, dst, n: int) -> None:
        """Scan n words of `src` into n + 1 words of `dst` (dst may be src only if it holds n + 1 words)."""
        self._level(src, dst, n, n + 1, 0)

    def _level(self, src, dst, n_in: int, n_out: int, level: int) -> None:
        blocks = math.ceil(n_out / self.BLOCK)
        sums = self._aux_buffer(level, blocks if blocks > 1 else 1)
        scan = self.shaders.compute("counted/scan_blocks.comp.j2", **self._vars())
        src.bind_to_storage_buffer(Buffer.SCAN_IN)
        dst.bind_to_storage_buffer(Buffer.SCAN_OUT)
        sums.bind_to_storage_buffer(Buffer.SCAN_SUMS)
        scan["gua_n_in"] = n_in
        scan["gua_n_out"] = n_out
        scan["gua_write_sums"] = blocks > 1
        scan.run(*dispatch_grid(blocks))
        self.ctx.memory_barrier()
        if blocks <= 1:
            return
        self._level(sums, sums, blocks, blocks, level + 1)  # block totals -> block offsets
        add = self.shaders.compute("counted/scan_add.comp.j2", **self._vars())
        dst.bind_to_storage_buffer(Buffer.SCAN_OUT)
        sums.bind_to_storage_buffer(Buffer.SCAN_SUMS)
        add["gua_n_out"] = n_out
        add.run(*dispatch_grid(blocks))
        self.ctx.memory_barrier()

    def aux_bytes(self) -> int:
        """Bytes held by the block-sum buffers."""
        return sum(b.size for b in self._aux if b is not None)

    def release(self) -> None:
        """Free the block-sum buffers."""
        for b in self._aux:
            if b is not None:
                b.release()
        self._aux = []
