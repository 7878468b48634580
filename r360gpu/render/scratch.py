"""Reusable device buffers for the renderer's intermediate results.

Every stage asks for its buffers by name; a buffer is reallocated only when a
larger size is requested, so rendering many views of one scene allocates
once.  Names must be unique among buffers alive in the same command encoder.
"""
from __future__ import annotations

from ..gpu.context import BufferRange, GpuContext

# Grow a little beyond the request so that slowly growing sizes (e.g. the key
# count over a camera path) do not reallocate every view.
_GROWTH = 1.25


class Scratch:
    """Named device buffers of at least a requested size (bytes)."""

    def __init__(self, ctx: GpuContext):
        self.ctx = ctx
        self._buffers: dict[str, object] = {}

    def get(self, name: str, nbytes: int):
        """A buffer named ``name`` holding at least ``nbytes`` bytes (contents undefined)."""
        nbytes = max(256, int(nbytes))
        buf = self._buffers.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.destroy()
                nbytes = int(nbytes * _GROWTH)
            nbytes = (nbytes + 255) // 256 * 256
            buf = self.ctx.buffer(nbytes, label=name)
            self._buffers[name] = buf
        return buf

    def window(self, name: str, nbytes: int) -> BufferRange:
        """The first ``nbytes`` bytes (at least 4) of buffer ``name`` as a binding window."""
        nbytes = max(4, (int(nbytes) + 3) // 4 * 4)
        return BufferRange(self.get(name, nbytes), 0, nbytes)

    def release(self) -> None:
        """Free every buffer now (instead of waiting for garbage collection)."""
        for buf in self._buffers.values():
            buf.destroy()
        self._buffers.clear()
