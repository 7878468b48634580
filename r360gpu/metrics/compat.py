"""The Remove360 reference pipeline's 8-bit ("compat") depth-change mask, in numpy.

The public reference code (github.com/simonakocour/anything_left,
``remove360/preprocessing/depth_diff.py``, ``process_depth_pair`` with
``save_intermediate=True``) does not threshold |ΔD| directly.  It

1. computes ``|D_post - D_pre|`` in float32, with 0 wherever either depth is 0
   (:func:`depth_delta`, which also treats NaN, inf and negative depths as
   missing);
2. writes it with ``matplotlib.pyplot.imsave(path, delta, cmap=gray_r)``:
   min-max normalisation (``matplotlib.colors.Normalize``), the 256-entry
   ``gray_r`` lookup table converted to bytes, an RGBA PNG;
3. reads the PNG back with PIL as RGBA and takes the max over R, G, B as the
   gray level (all three are equal for gray_r);
4. counts the 256 gray levels (bin edges -0.5 .. 255.5, positions 0..255),
   runs GHT with nu=1000, tau=300, kappa=0, omega=0, and marks
   ``gray < t`` as changed.  gray_r is reversed (large |ΔD| -> dark), so
   ``gray < t`` selects large depth changes.

:func:`compat_quantise` reproduces steps 2-3 bit for bit without matplotlib
(the arithmetic of matplotlib 3.11 under numpy 2: Normalize subtracts and
divides by float64 scalars and stores float32), and :func:`compat_changed`
adds step 4.  The reference then saves the mask with
``imsave(mask, cmap=gray_r)`` and reads it as "changed = gray != 255"; that
round trip returns the same mask, because ``gray < t`` can never hold for
every pixel (the smallest |ΔD| always maps to gray 255 and ``t <= 254``), so the
mask is never the constant image that imsave would write as all white.

Not reproduced: with ``save_intermediate=False`` (the default of
``batch_process_depths`` and of ``scripts/compute_depth_diff.py``, which
``scripts/run_pipeline.py`` calls without ``--save-intermediate``) the same
function skips steps 2-3 and histograms ``clip(|ΔD|, 0, 255).astype(uint8)``
directly: no min-max normalisation and no reversal, so its ``gray < t`` marks
the *small* depth changes.  The protocol's compat option follows the
normalised gray_r path above.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from r360gpu.errors import InputError
from r360gpu.metrics.ght import ght

N_LEVELS = 256
"""Entries of matplotlib's gray_r colormap (``Colormap.N``) and of the gray-level histogram."""


def _gray_r_bytes() -> np.ndarray:
    """The gray level matplotlib writes for each of the 256 gray_r colormap entries.

    matplotlib builds the gray_r table by sampling the segment (x=0 -> 1,
    x=1 -> 0) at ``x_i = 255 * linspace(0, 1, 256)[i] / 255`` and converts it
    to bytes with ``(lut * 255).astype(uint8)``, i.e. truncation.  The float
    round-off makes 38 entries one lower than ``255 - i`` (e.g. entries 43
    and 44 both give 211, and entries 254 and 255 both give 0), which is why
    this table is computed with the same float64 steps instead of as
    ``255 - i``.
    """
    samples = (N_LEVELS - 1) * np.linspace(0.0, 1.0, N_LEVELS)
    inner = samples[1:-1] / float(N_LEVELS - 1)
    levels = np.concatenate([[1.0], inner * (0.0 - 1.0) + 1.0, [0.0]])
    levels = np.clip(levels, 0.0, 1.0)
    return (levels * 255).astype(np.uint8)


_GRAY_R = _gray_r_bytes()


class CompatResult(NamedTuple):
    """Result of :func:`compat_changed`.

    changed: bool array (H, W), True where the reference marks a depth change.
    threshold: float, the GHT threshold on the gray-level axis (0..254);
        ``changed = gray < threshold``.
    hist: int64 array (256,), count of pixels at each gray level 0..255.
    """

    changed: np.ndarray
    threshold: float
    hist: np.ndarray


def _check_image(name: str, a, *, finite: bool = True) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 2 or a.size == 0:
        raise InputError(f"{name} must be a non-empty (H, W) array, got shape {a.shape}")
    if not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        raise InputError(f"{name} must hold numbers, got dtype {a.dtype}")
    with np.errstate(over="ignore"):
        a = a.astype(np.float32)
    if finite and not np.all(np.isfinite(a)):
        raise InputError(f"{name} has NaN, inf or values beyond the float32 range")
    return a


def depth_delta(depth_pre, depth_post) -> np.ndarray:
    """Absolute depth change with the reference's missing-depth rule.

    Args:
        depth_pre, depth_post: depth maps, shape (H, W), any real dtype (the
            reference reads 8-bit PNGs); converted to float32.  A depth is
            valid when finite and > 0; 0 means "no coverage", and NaN, inf and
            negative values count as missing too (as in
            :mod:`r360gpu.kernels.depth_change`).
    Returns:
        float32 (H, W): ``|depth_post - depth_pre|`` where both depths are
        valid, else 0.  The reference detects missing pixels by testing
        ``diff == depth_post`` or ``diff == -depth_pre`` on the float32
        difference, which for its 8-bit depths is exactly "either depth is
        0"; here the test is explicit, so a tiny nonzero depth beside a large
        one is not mistaken for a missing one.
    Raises:
        InputError: shapes differ, not 2-D, empty, or not numeric.
    """
    pre = _check_image("depth_pre", depth_pre, finite=False)
    post = _check_image("depth_post", depth_post, finite=False)
    if pre.shape != post.shape:
        raise InputError(f"depth maps differ in shape: pre {pre.shape}, post {post.shape}")
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(pre) & (pre > 0) & np.isfinite(post) & (post > 0)
        delta = np.abs(post - pre)
    return np.where(valid, delta, np.float32(0.0)).astype(np.float32)


def compat_quantise(delta) -> np.ndarray:
    """The 8-bit gray image the reference gets from ``imsave(delta, cmap=gray_r)``.

    Args:
        delta: |ΔD|, shape (H, W), finite; converted to float32 first, as the
            reference holds it in float32.
    Returns:
        uint8 (H, W) gray levels: ``gray_r[k]`` with ``k = floor(256 * s)``
        (``s == 1`` -> 255), ``s = (delta - min) / (max - min)`` evaluated as
        matplotlib does (float64 arithmetic, rounded to float32 after the
        subtraction and after the division); a constant image has ``s = 0``
        everywhere (gray 255).  Large |ΔD| is dark.
    Raises:
        InputError: not 2-D, empty, or non-finite values.
    """
    a = _check_image("delta", delta)
    vmin = float(a.min())
    vmax = float(a.max())
    if vmin == vmax:
        s = np.zeros(a.shape, dtype=np.float32)
    else:
        s = (a.astype(np.float64) - vmin).astype(np.float32)
        s = (s.astype(np.float64) / (vmax - vmin)).astype(np.float32)
    k = s * np.float32(N_LEVELS)
    # s == 1 is the top entry, not "over"; rounding can push s a hair above 1,
    # which matplotlib maps to the "over" colour, itself the top entry.
    k = np.minimum(k, np.float32(N_LEVELS - 1)).astype(np.intp)
    return _GRAY_R[k]


def compat_changed(
    delta,
    nu: float = 1000.0,
    tau: float = 300.0,
    kappa: float = 0.0,
    omega: float = 0.0,
) -> CompatResult:
    """The reference pipeline's changed-pixel mask for one view.

    Args:
        delta: |ΔD|, shape (H, W), finite (see :func:`depth_delta`); the whole
            image is histogrammed, not just the target mask.
        nu, tau, kappa, omega: GHT parameters; defaults are the reference's.
    Returns:
        :class:`CompatResult` ``(changed, threshold, hist)`` with
        ``changed = compat_quantise(delta) < threshold``.
    Raises:
        InputError: as :func:`compat_quantise`, or bad GHT parameters.
    """
    gray = compat_quantise(delta)
    hist = np.bincount(gray.ravel(), minlength=N_LEVELS).astype(np.int64)
    threshold = ght(hist, np.arange(N_LEVELS), nu=nu, tau=tau, kappa=kappa, omega=omega).threshold
    return CompatResult(gray < threshold, threshold, hist)
