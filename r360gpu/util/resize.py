"""The project's one nearest-neighbour resize rule.

Output pixel i of an axis of n_out pixels takes source pixel ``floor(i * n_in / n_out)``: what
``cv2.INTER_NEAREST`` picks (the public Remove360 scripts resize masks with it, and the report's
contact sheets follow it), checked against OpenCV in tests/test_protocol_nearest_resize.py.  Masks
read from disk (precomputed probe outputs), the viewer's overlays and the report's panels all use
it, so a mask resized anywhere in r360gpu is the same mask.  (Torch's "nearest" rule, which the
public semantic script applies to GSAM2 masks, is reproduced separately for parity only:
:func:`r360gpu.metrics.compat_public.resize_torch_nearest`.)
"""
from __future__ import annotations

import numpy as np


def nearest_index(n_in: int, n_out: int) -> np.ndarray:
    """int64 (n_out,): the source index of each output index, ``floor(i * n_in / n_out)``."""
    return (np.arange(int(n_out), dtype=np.int64) * int(n_in)) // int(n_out)


def resize_nearest(a: np.ndarray, size: tuple[int, int], *, axes: tuple[int, int] = (-2, -1)) -> np.ndarray:
    """``a`` resized to ``size`` = (height, width) along ``axes`` (rows, columns) by :func:`nearest_index`.

    Default axes: the last two ((K, H, W) mask stacks, (H, W) masks); ``axes=(0, 1)`` for (H, W, C)
    images.  Returned as is when the size already matches; an empty stack keeps its length.
    """
    a = np.asarray(a)
    out_h, out_w = int(size[0]), int(size[1])
    ra, ca = (ax % a.ndim for ax in axes)
    in_h, in_w = a.shape[ra], a.shape[ca]
    if (in_h, in_w) == (out_h, out_w):
        return a
    if in_h == 0 or in_w == 0:
        if a.size == 0 and a.ndim == 3 and a.shape[0] == 0 and (ra, ca) == (1, 2):
            return np.zeros((0, out_h, out_w), dtype=a.dtype)
        raise ValueError(f"cannot resize an array of size {(in_h, in_w)}")
    out = np.take(a, nearest_index(in_h, out_h), axis=ra)
    return np.ascontiguousarray(np.take(out, nearest_index(in_w, out_w), axis=ca))
