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


def no_depth_in_mask_reference(d_post, mask) -> int:
    """Pixels of ``mask`` where D_post is missing (not finite or <= 0): no depth after removal."""
    b = np.asarray(d_post, np.float32)
    with np.errstate(invalid="ignore"):
        missing = ~(np.isfinite(b) & (b > 0))
    return int((missing & (np.asarray(mask) != 0)).sum())


def ssim_reference(x, y, data_range: float = 1.0):
    """Mean SSIM and MSE of two (H, W, C) float64 images by the window definition:
    every 11 x 11 window wholly inside the image, the 2-D Gaussian weights
    (sigma 1.5, sum 1), population moments about the window means."""
    from numpy.lib.stride_tricks import sliding_window_view

    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    if x.ndim == 2:
        x, y = x[:, :, None], y[:, :, None]
    k = np.arange(11) - 5.0
    g = np.exp(-k * k / (2 * 1.5**2))
    w2 = np.outer(g, g)
    w2 /= w2.sum()
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    vals = []
    for ch in range(x.shape[2]):
        a = sliding_window_view(x[:, :, ch], (11, 11))  # (H-10, W-10, 11, 11)
        b = sliding_window_view(y[:, :, ch], (11, 11))
        ma = (a * w2).sum(axis=(2, 3))
        mb = (b * w2).sum(axis=(2, 3))
        da = a - ma[:, :, None, None]
        db = b - mb[:, :, None, None]
        va = (w2 * da * da).sum(axis=(2, 3))
        vb = (w2 * db * db).sum(axis=(2, 3))
        cov = (w2 * da * db).sum(axis=(2, 3))
        vals.append(((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2)))
    mse = float(np.mean((x - y) ** 2)) / (data_range * data_range)
    return float(np.mean(np.stack(vals))), mse
