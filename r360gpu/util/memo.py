"""Values made once per group of objects, told apart by identity (arrays are not hashable).

A view's contact sheets share their inputs as the very same array objects
(I_pre, I_ref, the probes' readings on them), so "made from these arrays"
is a question of identity.  The objects are kept in the memo beside the
value, so no id is reused by another object while the memo lives.
"""
from __future__ import annotations

from typing import Callable, Hashable

__all__ = ["ByIdentity"]


class ByIdentity:
    """``get(kind, objects, make)``: ``make()`` once per ``kind`` (any hashable, e.g. the
    function and its scalar arguments) and identity of each of ``objects``."""

    def __init__(self):
        self._made: dict = {}

    def get(self, kind: Hashable, objects: tuple, make: Callable[[], object]):
        key = (kind, tuple(id(o) for o in objects))
        hit = self._made.get(key)
        if hit is None:
            hit = self._made[key] = (objects, make())
        return hit[1]

    def __len__(self) -> int:
        return len(self._made)
