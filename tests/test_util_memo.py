"""ByIdentity: a value made once per kind and identity of its objects."""
from __future__ import annotations

import numpy as np

from r360gpu.util.memo import ByIdentity


def test_made_once_per_kind_and_identity_of_the_objects():
    memo, calls = ByIdentity(), []
    a, b = np.zeros(3), np.ones(2)

    def make(tag):
        calls.append(tag)
        return tag

    assert memo.get("k", (a, b), lambda: make(1)) == 1
    assert memo.get("k", (a, b), lambda: make(2)) == 1  # the same objects: not made again
    assert memo.get("k", (a.copy(), b), lambda: make(3)) == 3  # equal values, another object
    assert memo.get(("k", 2), (a, b), lambda: make(4)) == 4  # another kind
    assert memo.get("k", (b, a), lambda: make(5)) == 5  # order counts
    assert calls == [1, 3, 4, 5] and len(memo) == 4


def test_objects_are_kept_so_an_id_is_never_reused_inside_the_memo():
    memo = ByIdentity()
    for k in range(200):  # temporaries: without keeping them, a new array could take a freed id
        assert memo.get("k", (np.full(4, k),), lambda k=k: k) == k
