"""FID and KID between two sets of image features (float64, numpy / scipy).

The features are one row per image, e.g. the 2048 Inception pool3 activations of
`r360gpu.probes.inception.InceptionModel`; the reference set (the photographs
of the scene without the object) comes first, the method's renders second.

**FID** (Heusel et al., NeurIPS 2017) exactly as pytorch-fid (``fid_score.py``:
``calculate_activation_statistics`` then ``calculate_frechet_distance`` with
``eps = 1e-6``) computes it, branch for branch:

* ``mu`` = the mean over images, ``sigma = np.cov(features, rowvar=False)`` (sample
  covariance, divisor N - 1);
* ``covmean = sqrtm(sigma_ref . sigma_out)`` (``scipy.linalg.sqrtm``);
* if ``covmean`` has a non-finite entry (a singular product), ``eps`` is added to both
  covariances' diagonals and the square root taken again; pytorch-fid prints
  "fid calculation produces singular product"; here `Fid.offset_added` says so and
  a warning is raised (`r360gpu.util.warning_log.warn`);
* a complex ``covmean`` (rounding) keeps its real part when every diagonal imaginary part
  is within ``1e-3`` of 0 (``np.allclose(..., atol=1e-3)``); otherwise pytorch-fid raises
  "Imaginary component"; here FID is *not computed*: `Fid.value` is None and
  `Fid.reason` says why;
* ``FID = |mu_ref - mu_out|^2 + tr(sigma_ref) + tr(sigma_out) - 2 tr(covmean)``.

Fewer images than feature dimensions (30 test views against 2048 dimensions) leave both
covariances singular; pytorch-fid still computes, and so does this module (its value is
then biased upwards and depends on N: compare FIDs only over the same numbers of
images).  One image per set is refused (a covariance needs N >= 2; pytorch-fid's
``np.cov`` would give NaN).

**KID** (Binkowski et al., ICLR 2018, "Demystifying MMD GANs"): the unbiased estimate of
the squared maximum mean discrepancy with the polynomial kernel
``k(x, y) = (gamma x.y + coef)^degree``, ``degree = 3``, ``gamma = 1 / d``, ``coef = 1``,
averaged over random subsets, as torchmetrics' ``KernelInceptionDistance`` (1.x: ``poly_kernel``,
``maximum_mean_discrepancy``; mean and population standard deviation, ``std(unbiased=False)``,
over ``subsets``) and clean-fid's ``kernel_distance`` (the mean) define it.  Per subset of ``m`` rows of each set::

    MMD^2 = (sum_{i != j} k(x_i, x_j) + sum_{i != j} k(y_i, y_j)) / (m (m - 1))
            - 2 sum_{i, j} k(x_i, y_j) / m^2

``m = min(subset_size, N_ref, N_out)`` as clean-fid takes it (torchmetrics refuses a
``subset_size`` above N instead); each subset draws ``m`` rows of each set without
replacement from ``numpy.random.default_rng(seed)`` (the reference's rows first), so the
result is deterministic.  When ``m`` equals both set sizes every subset holds all rows and
the value is the full unbiased MMD^2.

**Which images**: pytorch-fid's ``calculate_fid_given_paths`` scores every file of each
folder whose name ends in one of its extensions (lower case only, as its ``glob`` does on
Linux), sorted by path: `fid_image_files` lists the same files.  (The 360-USID script
so compares all of ``test_images/`` with all of ``renders/``, not view pairs.)
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import linalg

from ..errors import InputError
from ..util import warning_log

#: pytorch-fid's ``calculate_frechet_distance`` default: added to the covariances' diagonals
#: when the square root of their product is not finite.
FID_EPS = 1e-6
#: The tolerance of pytorch-fid's check that ``covmean``'s diagonal is real.
FID_IMAG_ATOL = 1e-3
#: torchmetrics' ``KernelInceptionDistance`` defaults (clean-fid's ``num_subsets`` and
#: ``max_subset_size`` are the same).
KID_SUBSETS = 100
KID_SUBSET_SIZE = 1000
KID_DEGREE = 3
KID_COEF = 1.0
#: The file extensions pytorch-fid reads from a folder (``fid_score.IMAGE_EXTENSIONS``).
FID_IMAGE_EXTENSIONS = ("bmp", "jpg", "jpeg", "pgm", "png", "ppm", "tif", "tiff", "webp")


def fid_image_files(folder: str | os.PathLike) -> list[Path]:
    """The images pytorch-fid takes from ``folder``: files named ``*.EXT`` for its lower-case
    extensions, sorted (a folder so named, which pytorch-fid would list and fail to open, is
    left out).  A missing folder is an InputError naming it."""
    root = Path(folder)
    if not root.is_dir():
        raise InputError("FID image folder not found", root)
    return sorted(p for ext in FID_IMAGE_EXTENSIONS for p in root.glob(f"*.{ext}") if p.is_file())


def _features(x, what: str) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] < 1:
        raise InputError(f"{what} features must be a (N, d) array, got shape {a.shape}")
    if a.shape[0] < 2:
        raise InputError(f"{what}: {a.shape[0]} image(s); FID and KID need at least 2 images per set")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise InputError(f"{what} features must be real numbers, got dtype {a.dtype}")
    out = a.astype(np.float64)
    if not np.isfinite(out).all():
        raise InputError(f"{what} features contain NaN or infinite values")
    return out


def _feature_pair(ref, out) -> tuple[np.ndarray, np.ndarray]:
    r = _features(ref, "reference")
    o = _features(out, "method")
    if r.shape[1] != o.shape[1]:
        raise InputError(f"the reference features have {r.shape[1]} dimensions, the method's {o.shape[1]}")
    return r, o


@dataclass(frozen=True)
class Fid:
    """One FID.

    value: the distance (None when not computed, with ``reason``); offset_added: the
    square root of the covariances' product was not finite and ``eps`` was added to their
    diagonals (pytorch-fid's singular-product branch); n_ref, n_out: images per set
    (None when computed from statistics by `frechet_distance`).
    """

    value: float | None
    reason: str | None
    offset_added: bool
    n_ref: int | None = None
    n_out: int | None = None


def frechet_distance(mu1, sigma1, mu2, sigma2, eps: float = FID_EPS) -> Fid:
    """The Frechet distance of two Gaussians, as pytorch-fid's ``calculate_frechet_distance``.

    mu: (d,), sigma: (d, d), float64.  See the module docstring for the branches.
    """
    mu1, mu2 = np.atleast_1d(mu1), np.atleast_1d(mu2)
    sigma1, sigma2 = np.atleast_2d(sigma1), np.atleast_2d(sigma2)
    if mu1.shape != mu2.shape or sigma1.shape != sigma2.shape or sigma1.shape != (mu1.size, mu1.size):
        raise InputError(
            f"Gaussians of different sizes: means {mu1.shape} and {mu2.shape}, covariances {sigma1.shape} and {sigma2.shape}"
        )
    diff = mu1 - mu2
    with warnings.catch_warnings():
        # scipy warns of every singular product; below d + 1 images every product is one.
        warnings.simplefilter("ignore", linalg.LinAlgWarning)
        covmean = linalg.sqrtm(sigma1.dot(sigma2))
        offset_added = not np.isfinite(covmean).all()
        if offset_added:
            offset = np.eye(sigma1.shape[0]) * eps
            covmean = linalg.sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=FID_IMAG_ATOL):
            m = float(np.max(np.abs(covmean.imag)))
            return Fid(None, f"the square root of the covariances' product has an imaginary component "
                             f"of up to {m:.6g} (pytorch-fid stops here)", offset_added)
        covmean = covmean.real
    tr_covmean = np.trace(covmean)
    value = float(diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2 * tr_covmean)
    return Fid(value, None, offset_added)


def _statistics(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mu, sigma) of checked float64 features, as pytorch-fid's ``calculate_activation_statistics``."""
    return np.mean(f, axis=0), np.cov(f, rowvar=False)


def feature_statistics(features) -> tuple[np.ndarray, np.ndarray]:
    """(mu (d,), sigma (d, d)) float64 of (N, d) features (N >= 2), for `frechet_distance`."""
    return _statistics(_features(features, "image"))


def fid_from_features(ref, out, *, eps: float = FID_EPS, what: str | None = None) -> Fid:
    """FID between the reference's (N_ref, d) and the method's (N_out, d) features.

    Any real dtype; computed in float64.  what: names the comparison in the warning raised
    when the singular-product branch is taken (e.g. "scene cone, method ours").
    """
    r, o = _feature_pair(ref, out)
    res = frechet_distance(*_statistics(r), *_statistics(o), eps)
    if res.offset_added:
        warning_log.warn(
            f"FID{' of ' + what if what else ''}: the covariances' product is singular "
            f"({r.shape[0]} and {o.shape[0]} images, {r.shape[1]} dimensions); {eps:g} added to their diagonals, as pytorch-fid does"
        )
    return Fid(res.value, res.reason, res.offset_added, r.shape[0], o.shape[0])


@dataclass(frozen=True)
class Kid:
    """One KID: mean and population standard deviation (as torchmetrics) of the unbiased
    MMD^2 over ``subsets`` subsets of ``subset_size`` rows of each set."""

    mean: float
    std: float
    subsets: int
    subset_size: int


def polynomial_mmd2(x: np.ndarray, y: np.ndarray, degree: int = KID_DEGREE, gamma: float | None = None,
                    coef: float = KID_COEF) -> float:
    """Unbiased MMD^2 of two (m, d) float64 sets of the same size with the polynomial kernel."""
    m = x.shape[0]
    g = 1.0 / x.shape[1] if gamma is None else gamma
    k_xx = (g * (x @ x.T) + coef) ** degree
    k_yy = (g * (y @ y.T) + coef) ** degree
    k_xy = (g * (x @ y.T) + coef) ** degree
    off_diag = (k_xx.sum() - np.trace(k_xx)) + (k_yy.sum() - np.trace(k_yy))
    return float(off_diag / (m * (m - 1)) - 2.0 * k_xy.sum() / (m * m))


def kid_from_features(ref, out, *, subsets: int = KID_SUBSETS, subset_size: int = KID_SUBSET_SIZE,
                      degree: int = KID_DEGREE, gamma: float | None = None, coef: float = KID_COEF,
                      seed: int = 0) -> Kid:
    """KID between the reference's (N_ref, d) and the method's (N_out, d) features.

    See the module docstring for the definition and the subset draws; gamma None is 1 / d.
    """
    r, o = _feature_pair(ref, out)
    if subsets < 1:
        raise InputError(f"KID needs at least one subset, got subsets={subsets}")
    if subset_size < 2:
        raise InputError(f"KID needs subsets of at least 2 images, got subset_size={subset_size}")
    if gamma is not None and not (math.isfinite(gamma) and gamma > 0):
        raise InputError(f"KID's kernel gamma must be a positive number, got {gamma}")
    m = min(subset_size, r.shape[0], o.shape[0])
    rng = np.random.default_rng(seed)
    vals = np.empty(subsets)
    for s in range(subsets):
        ir = rng.choice(r.shape[0], m, replace=False)
        io = rng.choice(o.shape[0], m, replace=False)
        vals[s] = polynomial_mmd2(r[ir], o[io], degree, gamma, coef)
    return Kid(float(np.mean(vals)), float(np.std(vals)), subsets, m)
