"""Renders made before scoring, handed to it so that no view of a source is rendered twice.

The synthetic generator renders every view of a bundle's reference scene to
draw the target masks (:mod:`r360gpu.synthetic.masks`); scoring needs the
same renders again.  ``r360gpu demo`` keeps them in a :class:`KeptRenders`
and scoring takes each one instead of rendering it.

A kept render stands for a new one only when everything the render depends
on is the same: the splat file (resolved path, size and modification time),
the source's description (Gaussian count, SH degree, depth mode, render
options), the background colour, the GPU context object and every number of
the camera.  Anything else renders afresh, so a kept render can change no
result.  Each is handed out once, and the store holds at most ``budget``
bytes (further renders are not kept: they are rendered again, as without it).
"""
from __future__ import annotations

import json
import threading
from pathlib import Path

__all__ = ["KeptRenders"]

#: Bytes of renders a KeptRenders holds by default (16 views of two 480x360 scenes take 110 MB).
DEFAULT_BUDGET = 512 * 2**20


def _nbytes(images) -> int:
    return sum(a.nbytes for a in (images.rgb, images.depth, images.alpha) if a is not None)


def _key(source, camera) -> tuple | None:
    """What a render of ``source`` at ``camera`` depends on; None for sources that are not splat files."""
    if source.kind != "scene" or camera is None or source.path == "<in memory>":
        return None
    path = Path(source.path).resolve()
    try:
        st = path.stat()
    except OSError:
        return None
    desc = {k: v for k, v in source.describe().items() if k != "path"}
    return (str(path), st.st_size, st.st_mtime_ns, json.dumps(desc, sort_keys=True, default=str),
            tuple(float(c) for c in source.background), id(source.renderer.ctx), camera.key())


class KeptRenders:
    """A store of :class:`~r360gpu.render.sources.ViewImages` by what made them (module docstring)."""

    def __init__(self, budget: int = DEFAULT_BUDGET):
        self.budget = int(budget)
        self._kept: dict = {}
        self._bytes = 0
        self._lock = threading.Lock()
        self.taken = 0

    def keep(self, source, camera, images) -> bool:
        """Keep ``images`` (the render of splat source ``source`` at ``camera``); False when not kept."""
        key = _key(source, camera)
        size = _nbytes(images)
        with self._lock:
            if key is None or key in self._kept or self._bytes + size > self.budget:
                return False
            self._kept[key] = images
            self._bytes += size
        return True

    def take(self, source, camera):
        """The kept render of ``source`` at ``camera`` (removed from the store), or None."""
        if not self._kept:  # (every render of a run asks: no key work once the store is empty)
            return None
        key = _key(source, camera)
        with self._lock:
            images = self._kept.pop(key, None) if key is not None else None
            if images is not None:
                self._bytes -= _nbytes(images)
                self.taken += 1
        return images

    def __len__(self) -> int:
        return len(self._kept)

    def clear(self) -> None:
        with self._lock:
            self._kept.clear()
            self._bytes = 0
