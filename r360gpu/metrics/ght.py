"""Generalized Histogram Thresholding (GHT) on a host-side histogram.

Barron, "A Generalization of Otsu's Method and Minimum Error Thresholding",
ECCV 2020.  The geometric axis thresholds the per-view histogram of |ΔD| with
GHT (docs/protocol.md, "Geometric"); the GPU kernel builds the histogram and
this module picks the split.

Conventions
-----------
* A histogram of ``L`` bins has ``L - 1`` splits.  Split ``i`` puts bins
  ``0..i`` in class 0 and bins ``i+1..L-1`` in class 1; its position is
  ``x[i]``, the position of the last class-0 bin (Barron's convention).
* ``x`` defaults to the bin indices ``0..L-1`` (the Remove360 reference passes
  exactly that for its 256 gray levels), so the returned threshold is then in
  bin-index units; :func:`threshold_value` maps it to a data value.
* The objective is evaluated with the same cumulative-sum arithmetic as the
  paper (means ``mu = S1 / w``, scatter ``d = S2 - w * mu**2``, suffix sums
  accumulated from the top bin down) so that float64 scores, and therefore
  exact ties, are the same as in the reference implementation.

Degenerate histograms
---------------------
* Length 1: there is no split; the threshold is ``x[0]`` and ``scores`` is
  empty.
* All counts zero, or all mass in a single bin (and ``kappa == 0``): every
  split scores the same, so the tie rule returns the mean of ``x[:-1]``
  (127.0 for 256 bins indexed 0..255).  This is what the reference code
  returns too.  In depth units (:func:`threshold_value`) a constant |ΔD| has
  ``lo == hi`` and the threshold is ``lo``, so no pixel is "changed".
The result is never NaN: bad input raises :class:`~r360gpu.errors.InputError`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from r360gpu.errors import InputError
from r360gpu.protocol import GHT_BINS, GHT_KAPPA, GHT_NU, GHT_OMEGA, GHT_TAU

# Floor applied to class weights and variances, as in the paper; it keeps the
# logarithms finite for empty classes and zero-scatter classes.
_FLOOR = 1e-30


class GhtResult(NamedTuple):
    """Result of :func:`ght`.

    threshold: float, position (in ``x`` units) of the chosen split; the mean
        of the positions of all splits that reach the maximum score.
    scores: float64 array of shape ``(L - 1,)``, the objective ``f0 + f1`` of
        every split ``i`` (bins ``0..i`` vs ``i+1..L-1``).
    """

    threshold: float
    scores: np.ndarray


def _floor(z: np.ndarray) -> np.ndarray:
    return np.maximum(_FLOOR, z)


def _prefix(z: np.ndarray) -> np.ndarray:
    """Sum of ``z[0..i]`` for every split ``i`` (length ``L - 1``)."""
    return np.cumsum(z)[:-1]


def _suffix(z: np.ndarray) -> np.ndarray:
    """Sum of ``z[i+1..L-1]`` for every split ``i``, accumulated from the top."""
    return np.cumsum(z[::-1])[::-1][1:]


def _check_histogram(hist) -> np.ndarray:
    n = np.asarray(hist)
    if n.ndim != 1 or n.size == 0:
        raise InputError(f"GHT needs a non-empty 1-D histogram, got shape {n.shape}")
    if not (np.issubdtype(n.dtype, np.integer) or np.issubdtype(n.dtype, np.floating)):
        raise InputError(f"GHT histogram must hold numbers, got dtype {n.dtype}")
    n = n.astype(np.float64)
    if not np.all(np.isfinite(n)):
        raise InputError("GHT histogram has non-finite counts")
    if np.any(n < 0):
        raise InputError("GHT histogram has negative counts")
    return n


def _check_positions(x, length: int) -> np.ndarray:
    if x is None:
        return np.arange(length, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (length,):
        raise InputError(f"GHT bin positions have shape {x.shape}, expected ({length},)")
    if not np.all(np.isfinite(x)):
        raise InputError("GHT bin positions are not finite")
    if np.any(x[1:] < x[:-1]):
        raise InputError("GHT bin positions must be non-decreasing")
    return x


def _check_parameters(nu: float, tau: float, kappa: float, omega: float) -> None:
    for name, value in (("nu", nu), ("tau", tau), ("kappa", kappa), ("omega", omega)):
        if not np.isfinite(value):
            raise InputError(f"GHT parameter {name} must be finite, got {value!r}")
    if nu < 0 or tau < 0 or kappa < 0:
        raise InputError(f"GHT parameters nu, tau, kappa must be >= 0, got {nu!r}, {tau!r}, {kappa!r}")
    if not 0.0 <= omega <= 1.0:
        raise InputError(f"GHT parameter omega must lie in [0, 1], got {omega!r}")


def ght(
    hist,
    x=None,
    nu: float = GHT_NU,
    tau: float = GHT_TAU,
    kappa: float = GHT_KAPPA,
    omega: float = GHT_OMEGA,
) -> GhtResult:
    """Pick the split of a histogram that maximises the GHT objective.

    Args:
        hist: counts, array-like of shape ``(L,)``, ``L >= 1``, finite and
            non-negative (integer or float).
        x: bin positions, shape ``(L,)``, non-decreasing; default ``0..L-1``.
        nu: strength of the scaled-inverse-chi-squared prior on the class
            variances (Barron's nu); 0 turns the prior off.
        tau: prior standard deviation of each class, in ``x`` units.
        kappa: strength of the beta prior on the class-0 fraction.
        omega: mode of that beta prior (only matters when ``kappa > 0``).
        Defaults are the Remove360 reference values (nu=1000, tau=300,
        kappa=0, omega=0).  Barron's limits: nu=0, tau=0, kappa=0 is Minimum
        Error Thresholding; nu -> inf with tau -> 0 (e.g. nu=1e30, tau=1e-6)
        is Otsu's method; kappa -> inf is the omega-th weighted percentile.

    Returns:
        :class:`GhtResult` ``(threshold, scores)``.  With ``w_k`` the class
        counts, ``p_k = w_k / (w_0 + w_1)``, ``d_k`` the class scatter
        ``sum n (x - mu_k)^2`` and ``omega_0 = omega``, ``omega_1 = 1 - omega``:
        ``v_k = max(1e-30, (p_k nu tau^2 + d_k) / (p_k nu + w_k))`` and
        ``f_k = -d_k / v_k - w_k log v_k + 2 (w_k + kappa omega_k) log w_k``;
        ``scores = f_0 + f_1`` per split and ``threshold`` is the mean position
        of the maximising splits.  Counts ``w_k`` are floored at 1e-30.

    Raises:
        InputError: empty or non-1-D histogram, negative or non-finite counts,
            bad positions or parameters, or counts so large that the objective
            overflows.
    """
    n = _check_histogram(hist)
    x = _check_positions(x, n.size)
    _check_parameters(nu, tau, kappa, omega)
    if n.size == 1:
        return GhtResult(float(x[0]), np.empty(0, dtype=np.float64))
    nu, tau, kappa, omega = (np.float64(v) for v in (nu, tau, kappa, omega))

    # Overflow shows up as a non-finite score, reported below as an InputError.
    with np.errstate(over="ignore", invalid="ignore"):
        scores = _scores(n, x, nu, tau, kappa, omega)
    if not np.all(np.isfinite(scores)):
        raise InputError("GHT objective overflowed: histogram counts or positions are too large")

    best = scores == np.max(scores)
    return GhtResult(float(np.mean(x[:-1][best])), scores)


def _scores(n: np.ndarray, x: np.ndarray, nu: float, tau: float, kappa: float, omega: float) -> np.ndarray:
    """The GHT objective f0 + f1 of every split, float64 (L - 1,)."""
    nx = n * x
    nxx = n * x**2
    w0 = _floor(_prefix(n))
    w1 = _floor(_suffix(n))
    p0 = w0 / (w0 + w1)
    p1 = w1 / (w0 + w1)
    mu0 = _prefix(nx) / w0
    mu1 = _suffix(nx) / w1
    d0 = _prefix(nxx) - w0 * mu0**2
    d1 = _suffix(nxx) - w1 * mu1**2

    v0 = _floor((p0 * nu * tau**2 + d0) / (p0 * nu + w0))
    v1 = _floor((p1 * nu * tau**2 + d1) / (p1 * nu + w1))
    f0 = -d0 / v0 - w0 * np.log(v0) + 2 * (w0 + kappa * omega) * np.log(w0)
    f1 = -d1 / v1 - w1 * np.log(v1) + 2 * (w1 + kappa * (1 - omega)) * np.log(w1)
    return f0 + f1


def threshold_value(threshold: float, lo: float, hi: float, n_bins: int = GHT_BINS) -> float:
    """Map a GHT threshold in bin-index units to a data value.

    The histogram is assumed to have ``n_bins`` equal bins spanning
    ``[lo, hi]``: bin ``i`` holds values in ``[lo + i*w, lo + (i+1)*w)`` with
    ``w = (hi - lo) / n_bins``, the last bin also holding ``hi`` (the binning
    of ``np.histogram(values, n_bins, range=(lo, hi))``).  GHT run with the
    default positions ``x = 0..n_bins-1`` returns split position ``t``: bins
    ``0..t`` are class 0 (unchanged), bins ``t+1..`` class 1 (changed).  The
    returned value is the upper edge of bin ``t``,

        xi = lo + (t + 1) * (hi - lo) / n_bins,

    so ``values > xi`` selects class 1, except values lying exactly on that
    edge, which the binning puts in bin ``t + 1``; where that matters, compare
    bin indices (``bin_index > t``) instead of values.  A fractional ``t``
    (the mean of tied splits ``m..m+k``, whose bins ``m+1..m+k`` are empty)
    maps linearly and lands inside the empty run, so it separates the same
    two classes.  With ``hi == lo`` the result is ``lo`` and ``values > xi``
    selects nothing.

    Note: the Remove360 reference code does not threshold float depths; it
    thresholds the 8-bit gray_r image of |ΔD| (see
    :mod:`r360gpu.metrics.compat`) with ``gray < t_gray``.  Because gray_r
    reverses the axis (gray ~ 255 - bin) and ``<`` excludes the level
    ``t_gray`` that GHT put in the changed class, that corresponds to
    ``bin_index >= floor(t) + 2`` on this axis: one boundary bin fewer than
    the GHT split.  It is not exact, because gray_r's byte table merges some
    neighbouring bins.

    Args:
        threshold: GHT threshold in bin-index units, in ``[0, n_bins - 2]``.
        lo, hi: histogram range (min and max of the data), ``lo <= hi``, finite.
        n_bins: number of bins, >= 2.

    Returns:
        The threshold in data units (float).
    """
    if n_bins < 2:
        raise InputError(f"threshold_value needs n_bins >= 2, got {n_bins}")
    if not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(threshold)):
        raise InputError(f"threshold_value needs finite arguments, got t={threshold!r}, lo={lo!r}, hi={hi!r}")
    if hi < lo:
        raise InputError(f"threshold_value needs lo <= hi, got lo={lo!r}, hi={hi!r}")
    if not 0.0 <= threshold <= n_bins - 2:
        raise InputError(f"GHT threshold {threshold!r} lies outside the split range [0, {n_bins - 2}]")
    return float(lo + (threshold + 1.0) * (hi - lo) / n_bins)
