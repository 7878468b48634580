"""What consecutive frames of one shape share on the host: bind groups and uniform buffers.

wgpu cannot replay a recorded command buffer, so a renderer records every
frame's passes again; what it need not do again is create their bind groups
and uniform buffers, which was most of the host's cost of recording a pass.
While a `FrameCache` is active on a thread (`GpuContext.recording`):

* the ``i``-th uniform a frame asks for is the cache's ``i``-th uniform buffer,
  rewritten in place (a queue write, ordered after every earlier submission)
  only when its contents changed since the previous frame;
* a bind group is looked up by its pipeline and the exact buffers, offsets and
  sizes it binds; one used in the frame before is reused.

A frame of the same shape asks for the same uniforms in the same order and
binds the same scratch buffers, so it creates neither.  Each uniform buffer
serves one request per frame, so rewriting it for the next frame cannot
change a pass of the current one.  Entries not used in the last frame are
dropped, so no more than two frames' bind groups (and the buffers they hold)
are kept.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


class FrameCache:
    """Bind groups and uniform buffers kept from one frame to the next (see the module)."""

    def __init__(self):
        self._groups: dict = {}
        self._previous: dict = {}
        self._uniforms: list = []
        self._words: list[bytes] = []
        self._next = 0
        #: bind groups created and reused, and uniform buffers created and rewritten, since creation
        self.counts = dict(groups_created=0, groups_reused=0, uniforms_created=0, uniforms_written=0)

    def begin_frame(self) -> None:
        """Start a frame: uniform requests count from the first again; bind groups the frame
        before this one did not use are dropped."""
        self._previous, self._groups = self._groups, {}
        self._next = 0

    def uniform(self, words: np.ndarray, create: Callable, write: Callable):
        """The uniform buffer of this frame's next request, holding ``words`` (u32 array):
        kept (``write(buffer, words)`` when its contents differ) or ``create()`` (holding them)."""
        i, data = self._next, words.tobytes()
        self._next += 1
        if i < len(self._uniforms) and self._uniforms[i].size == len(data):
            if self._words[i] != data:
                write(self._uniforms[i], words)
                self._words[i] = data
                self.counts["uniforms_written"] += 1
            return self._uniforms[i]
        buf = create()
        self.counts["uniforms_created"] += 1
        if i < len(self._uniforms):
            self._uniforms[i], self._words[i] = buf, data
        else:
            self._uniforms.append(buf)
            self._words.append(data)
        return buf

    def bind_group(self, key, create):
        """The bind group for ``key`` (pipeline, group, bound ranges): kept, or ``create()``."""
        group = self._groups.get(key)
        if group is None:
            group = self._previous.pop(key, None)
            if group is None:
                group = create()
                self.counts["groups_created"] += 1
            else:
                self.counts["groups_reused"] += 1
            self._groups[key] = group
        else:
            self.counts["groups_reused"] += 1
        return group

    def clear(self) -> None:
        """Drop every bind group and free every uniform buffer now."""
        self._groups.clear()
        self._previous.clear()
        for buf in self._uniforms:
            buf.destroy()
        self._uniforms.clear()
        self._words.clear()
        self._next = 0
