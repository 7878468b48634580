"""Shared image plumbing of the weight-free built-in probes.

The built-in probes (:mod:`r360gpu.probes.builtin_semantic`,
:mod:`r360gpu.probes.builtin_structural`) are the embedded default that lets
scoring run anywhere, with no model weights.  Both work on a downscaled copy
of the rendering (the *working image*, long side at most a few hundred
pixels) and bring their label images back to the view's size with
nearest-neighbour sampling.  This module holds those steps:

* :func:`as_rgb_uint8` -- a view's image as uint8 RGB (float 0..1 is scaled);
* :func:`working_size` / :func:`to_working` -- the downscaled working image;
* :func:`label_masks` -- bool (K, H, W) masks at the view's size from a
  working-resolution label image (:func:`lut_masks`: from tables over its labels).
"""
from __future__ import annotations

import cv2
import numpy as np

from r360gpu.errors import InputError

__all__ = ["as_rgb_uint8", "working_size", "to_working", "upsample_rows_cols", "label_masks", "lut_masks"]


def as_rgb_uint8(image, what: str = "image") -> np.ndarray:
    """An RGB image as contiguous uint8 (H, W, 3).

    image: (H, W, 3) uint8 0..255, or any float dtype 0..1 (values outside are
        clipped, then scaled by 255 and rounded to nearest).
    what: how error messages name the image (e.g. ``"view '00012'"``).

    Raises InputError for another shape or dtype, or non-finite float values.
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"{what}: image must be (H, W, 3) RGB, got shape {arr.shape}")
    if arr.dtype == np.uint8:
        return np.ascontiguousarray(arr)
    if not np.issubdtype(arr.dtype, np.floating):
        raise InputError(f"{what}: image must be uint8 0..255 or float 0..1, got dtype {arr.dtype}")
    if not np.isfinite(arr).all():
        raise InputError(f"{what}: image has NaN or infinite values")
    scaled = np.rint(np.clip(arr.astype(np.float32), 0.0, 1.0) * np.float32(255.0))
    return np.ascontiguousarray(scaled.astype(np.uint8))


def working_size(height: int, width: int, long_side: int) -> tuple[int, int]:
    """(h, w) of the working image: the view shrunk so its long side is at most
    ``long_side`` pixels, aspect kept (rounded, at least 1); never enlarged."""
    height, width = int(height), int(width)
    longest = max(height, width)
    if longest <= long_side:
        return height, width
    scale = long_side / longest
    return max(1, int(round(height * scale))), max(1, int(round(width * scale)))


def to_working(rgb: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """uint8 (h, w, 3) working image from uint8 (H, W, 3) by area averaging
    (cv2.INTER_AREA), or ``rgb`` itself when it already has that size."""
    h, w = size
    if rgb.shape[:2] == (h, w):
        return rgb
    return cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)


def upsample_rows_cols(small: tuple[int, int], size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Source row and column of each output pixel for a nearest-neighbour
    resize from ``small`` (h, w) to ``size`` (H, W), pixel-centre aligned:
    source index = floor((i + 0.5) * in / out).  int64 (H,) and (W,)."""
    (h, w), (out_h, out_w) = small, size
    rows = np.minimum(((np.arange(out_h) + 0.5) * (h / out_h)).astype(np.int64), h - 1)
    cols = np.minimum(((np.arange(out_w) + 0.5) * (w / out_w)).astype(np.int64), w - 1)
    return rows, cols


def label_masks(labels: np.ndarray, ids: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """One bool mask per label id, at the view's size.

    labels: int (h, w) label image at working resolution.
    ids: int (K,) label values to return, in output order (distinct).
    size: (H, W) of the view; labels are upsampled by nearest neighbour
        (:func:`upsample_rows_cols`).

    Returns bool (K, H, W); mask k is ``labels_upsampled == ids[k]``.
    """
    out_h, out_w = int(size[0]), int(size[1])
    ids = np.asarray(ids, dtype=np.int64)
    k = ids.shape[0]
    if k == 0:
        return np.zeros((0, out_h, out_w), bool)
    # Map every label to its output slot (-1: not returned) once, so building
    # the stack costs one pass over the pixels rather than one per mask.
    lo = int(min(labels.min(), ids.min()))
    hi = int(max(labels.max(), ids.max()))
    slot = np.full(hi - lo + 1, -1, np.int64)
    slot[ids - lo] = np.arange(k)
    return lut_masks(labels if lo == 0 else labels.astype(np.int64) - lo, [slot], k, (out_h, out_w))


def lut_masks(labels: np.ndarray, luts, k: int, size: tuple[int, int]) -> np.ndarray:
    """bool (K, H, W) masks from a label image and tables over its labels.

    labels: int (h, w) label image at working resolution, values 0..n-1.
    luts: int64 (n,) tables, each mapping a label to the mask its pixels
        belong to (0..k-1) or -1 (none); a pixel can be in one mask per table.
    size: (H, W) of the view; labels are upsampled by nearest neighbour
        (:func:`upsample_rows_cols`), which commutes with the tables.
    """
    out_h, out_w = int(size[0]), int(size[1])
    hw = out_h * out_w
    masks = np.zeros(k * hw, bool)
    if k == 0:
        return masks.reshape(0, out_h, out_w)
    if labels.shape != (out_h, out_w):
        rows, cols = upsample_rows_cols(labels.shape, (out_h, out_w))
        labels = labels[rows[:, None], cols[None, :]]
    flat = labels.reshape(-1)
    for lut in luts:
        slot = lut[flat]
        keep = np.flatnonzero(slot >= 0)
        masks[slot[keep] * hw + keep] = True
    return masks.reshape(k, out_h, out_w)
