"""The public Remove360 scripts' depth-change mask, in numpy (the ``--compat`` modes).

The public evaluation code (github.com/simonakocour/anything_left, commit
dd0aad8, ``remove360/preprocessing/depth_diff.py``, ``process_depth_pair``)
does not threshold |ΔD| of float depths.  Per view it

1. reads both depth PNGs with PIL ``convert("L")`` (8-bit grey: RGB and
   palette images through ITU-R 601 luma, 16-bit ones clipped at 255), see
   :func:`read_depth_public`;
2. computes ``diff = D_post - D_pre`` in float32 and zeroes
   ``(diff == D_post) | (diff == -D_pre)``, where ``D_pre`` is uint8 so
   ``-D_pre`` wraps modulo 256: the first test zeroes the pixels whose pre
   depth is 0, the second matches nothing that is not already 0, so pixels
   whose POST depth alone is 0 keep ``|ΔD| = D_pre`` (:func:`public_delta`);
3. ``save_intermediate=True`` (mode ``"public"``; ``process_depth_pair``'s own
   default and ``scripts/compute_depth_diff.py --save-intermediate``): writes
   |ΔD| with ``matplotlib.pyplot.imsave(cmap=gray_r)`` (min-max normalisation,
   the 256-entry gray_r table in bytes), reads the PNG back as RGBA and takes
   the max over R, G, B (:func:`compat_quantise`); large |ΔD| is dark.
   ``save_intermediate=False`` (mode ``"public-default"``; the default of
   ``batch_process_depths`` and of ``scripts/compute_depth_diff.py``, which
   ``scripts/run_pipeline.py`` runs): the gray image is
   ``clip(|ΔD|, 0, 255).astype(uint8)``, not normalised and not reversed;
4. histograms the 256 gray levels, runs GHT (nu=1000, tau=300, kappa=0,
   omega=0) and marks ``gray < t``.  In mode ``"public"`` that selects the
   LARGE depth changes; in mode ``"public-default"`` it selects the SMALL
   ones (pixels whose |ΔD| lies below the split), which is what the scripts'
   default pipeline reports as "changed";
5. saves the mask with ``imsave(mask, cmap=gray_r)`` and the evaluation reads
   it back as "changed = gray != 255": a mask that is constant (all True or
   all False) is written all white, i.e. nothing changed (:func:`public_changed`).

:func:`compat_quantise` reproduces step 3 (``"public"``) bit for bit without
matplotlib (the arithmetic of matplotlib 3.11 under numpy 2: Normalize
subtracts and divides by float64 scalars and stores float32); the tests
compare it with matplotlib itself, and ``tests/data/compat_public`` holds a
folder scored by the public modules themselves.
"""
from __future__ import annotations

import os
from typing import NamedTuple

import numpy as np

from r360gpu.errors import InputError
from r360gpu.metrics.ght import ght
from r360gpu.protocol import GHT_KAPPA, GHT_NU, GHT_OMEGA, GHT_TAU

N_LEVELS = 256
"""Entries of matplotlib's gray_r colormap (``Colormap.N``) and of the gray-level histogram."""

COMPAT_MODES = ("public", "public-default")
"""``public``: the scripts' ``save_intermediate=True`` path (gray_r PNG round trip);
``public-default``: their default ``save_intermediate=False`` path (raw 8-bit |ΔD|)."""


def check_compat(compat) -> str | None:
    """The compat mode named by ``compat``: None/False -> None (paper mode),
    True -> ``"public"`` (what ``--compat`` alone means), or a name of
    :data:`COMPAT_MODES`.  Anything else is an InputError."""
    if compat is None or compat is False:
        return None
    if compat is True:
        return "public"
    if isinstance(compat, str) and compat in COMPAT_MODES:
        return compat
    raise InputError(f"compat mode must be one of {', '.join(COMPAT_MODES)} (or True for 'public'), got {compat!r}")


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
    """Absolute depth change, 0 wherever either depth is missing (r360gpu's rule).

    This is the rule of r360gpu's default mode (and of its depth pictures),
    NOT the public scripts' rule: they keep ``|ΔD| = D_pre`` where only the
    post depth is missing (see :func:`public_delta`).

    Args:
        depth_pre, depth_post: depth maps, shape (H, W), any real dtype;
            converted to float32.  A depth is valid when finite and > 0; 0
            means "no coverage", and NaN, inf and negative values count as
            missing too (as in :mod:`r360gpu.kernels.depth_change`).
    Returns:
        float32 (H, W): ``|depth_post - depth_pre|`` where both depths are
        valid, else 0.
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
    nu: float = GHT_NU,
    tau: float = GHT_TAU,
    kappa: float = GHT_KAPPA,
    omega: float = GHT_OMEGA,
) -> CompatResult:
    """``gray < t`` of the ``"public"`` path for one view, before the mask PNG round trip
    (:func:`public_changed` adds it; the two differ only for a constant mask).

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


# --- the public scripts' depth path, step by step ---------------------------------------------

def read_depth_public(path: str | os.PathLike) -> np.ndarray:
    """A depth PNG as the scripts read it: ``np.array(Image.open(path).convert("L"))``.

    uint8 (H, W).  PIL's "L" conversion is the scripts' only depth decoding:
    RGB/RGBA/palette images become ITU-R 601 luma, 16-bit grey images are
    clipped at 255 (so most of a 16-bit depth map reads as 255).
    Raises InputError naming the file when it cannot be read or decoded.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return np.array(im.convert("L"))
    except (OSError, UnidentifiedImageError, ValueError) as e:
        raise InputError(f"cannot read depth image as the public scripts do (PIL convert('L')): {e}", path) from None


def public_delta(depth_pre, depth_post) -> np.ndarray:
    """|ΔD| with the scripts' missing-depth rule, float32 (H, W).

    For uint8 inputs (what :func:`read_depth_public` gives) this equals the
    scripts' ``diff = post - pre`` (float32), ``diff[(diff == post) |
    (diff == -pre)] = 0`` with ``-pre`` wrapping modulo 256, ``abs``: 0 where
    the PRE depth is 0; ``|post - pre|`` everywhere else, so a pixel whose post
    depth alone is 0 keeps ``D_pre``.  Other dtypes (float depth of a bundle
    that is not a public folder) get that same effective rule on float32
    values, with NaN, inf and negative depths first set to 0 (missing).
    Raises InputError on shape mismatch, non-2-D, empty or non-numeric input.
    """
    pre = _check_image("depth_pre", depth_pre, finite=False)
    post = _check_image("depth_post", depth_post, finite=False)
    if pre.shape != post.shape:
        raise InputError(f"depth maps differ in shape: pre {pre.shape}, post {post.shape}")
    with np.errstate(invalid="ignore"):
        pre = np.where(np.isfinite(pre) & (pre > 0), pre, np.float32(0.0))
        post = np.where(np.isfinite(post) & (post > 0), post, np.float32(0.0))
    return np.where(pre == 0, np.float32(0.0), np.abs(post - pre)).astype(np.float32)


def public_gray(delta, mode: str) -> np.ndarray:
    """The 8-bit image the scripts histogram: :func:`compat_quantise` for
    ``"public"``, ``clip(delta, 0, 255).astype(uint8)`` for ``"public-default"``."""
    mode = check_compat(mode)
    if mode == "public":
        return compat_quantise(delta)
    a = _check_image("delta", delta)
    return np.clip(a, 0, 255).astype(np.uint8)


def public_changed(
    delta,
    mode: str = "public",
    nu: float = GHT_NU,
    tau: float = GHT_TAU,
    kappa: float = GHT_KAPPA,
    omega: float = GHT_OMEGA,
) -> CompatResult:
    """The changed-pixel mask the scripts' depth evaluation reads for one view.

    ``gray < t`` (GHT on the 256-level histogram of :func:`public_gray`),
    then the mask PNG round trip: a constant mask (all True or all False) is
    written as an all-white image, which the evaluation reads as "no pixel
    changed".  ``threshold`` is ``t`` on the gray-level axis.
    """
    gray = public_gray(delta, mode)
    hist = np.bincount(gray.ravel(), minlength=N_LEVELS).astype(np.int64)
    threshold = ght(hist, np.arange(N_LEVELS), nu=nu, tau=tau, kappa=kappa, omega=omega).threshold
    mask = gray < threshold
    if mask.all():  # all False needs nothing: it already reads as unchanged
        mask = np.zeros_like(mask)
    return CompatResult(mask, threshold, hist)
