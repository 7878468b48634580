"""Plain numpy reference implementations of the measurement kernels.

Readable, not fast: the tests and ``r360gpu doctor`` compare the GPU kernels
against these on random and adversarial inputs.
"""
from __future__ import annotations

import numpy as np

from .depth_change import bin_scale


def mask_iou_reference(a: np.ndarray, b: np.ndarray):
    """Intersections (N, M) int64, areas (N,), (M,), IoU (N, M) (0 where the union is empty), pair by pair."""
    a = np.asarray(a) != 0
    b = np.asarray(b) != 0
    n, m = len(a), len(b)
    inter = np.zeros((n, m), np.int64)
    iou = np.zeros((n, m), np.float64)
    for i in range(n):
        for j in range(m):
            inter[i, j] = np.logical_and(a[i], b[j]).sum()
            union = np.logical_or(a[i], b[j]).sum()
            iou[i, j] = inter[i, j] / union if union else 0.0
    return inter, a.reshape(n, -1).sum(1), b.reshape(m, -1).sum(1), iou


def depth_change_reference(d_pre, d_post, mask, t):
    """dD with the missing-depth rule, [lo, hi], the float32 256-bin histogram,
    the changed mask ``bin > t`` and the counts inside ``mask``."""
    a = np.asarray(d_pre, np.float32)
    b = np.asarray(d_post, np.float32)
    with np.errstate(invalid="ignore"):
        va = np.isfinite(a) & (a > 0)
        vb = np.isfinite(b) & (b > 0)
        d = np.where(va & vb, np.abs(a - b), np.float32(0)).astype(np.float32)
    lo, hi = (float(d.min()), float(d.max())) if d.size else (0.0, 0.0)
    scale = bin_scale(lo, hi)
    bins = np.clip(np.floor((d - np.float32(lo)) * scale), 0, 255).astype(np.int64)
    hist = np.bincount(bins.ravel(), minlength=256)
    changed = bins > t
    mask = np.asarray(mask) != 0
    return d, lo, hi, hist, changed, int((changed & mask).sum()), int(mask.sum())
