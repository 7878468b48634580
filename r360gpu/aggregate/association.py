"""Association between evaluation axes (Supp. "Are the Three Axes Redundant?", tab:supp_axis_corr).

For two axes given as scenes x methods grids:

* ``rho``: Spearman rho over all S*M (scene, method) cells
  (``scipy.stats.spearmanr``; ties get average ranks);
* ``rho_centred``: the same after subtracting each scene's mean (over methods)
  from each axis, which removes the shared scene difficulty.  Centred values
  are rounded to 12 decimals so that cells tied in exact arithmetic stay tied.
  The paper's printed values (tab:supp_axis_corr: -0.130, 0.299, -0.222) come
  from unrounded float centring, where round-off splits such ties; on the
  paper's own per-scene inputs this reading gives -0.130, 0.298, -0.221;
* ``p_centred``: two-sided permutation p-value of ``rho_centred``: the method
  labels of the second axis are shuffled independently within every scene
  (which keeps the clustering by scene), and
  ``p = (1 + #{|rho_perm| >= |rho_centred|}) / (1 + n_perm)`` (the observed
  labelling counts as one permutation, so p is never 0);
* ``tau_mean``/``tau_sd``: mean and standard deviation over scenes of the
  within-scene Kendall tau-b over the M methods (``scipy.stats.kendalltau``).
  The sd uses ``ddof=0``: that reproduces the printed 0.45/0.35/0.32, while
  ddof=1 gives 0.47/0.37/0.33.  Scenes where tau is undefined (an axis
  constant over the methods of that scene) are left out; ``n_tau_scenes``
  says how many scenes entered.

Undefined statistics (constant input) are NaN.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..protocol import N_PERM
from .cells import AxisCells
from .ranks import average_ranks

#: Axis pairs reported by :func:`axis_association`, in the paper's order.
AXIS_PAIRS: dict[str, tuple[str, str]] = {
    "sem-geo": ("s_sem", "s_geo"),
    "sem-str": ("s_sem", "s_str"),
    "geo-str": ("s_geo", "s_str"),
}

# Centred values are rounded before ranking so that cells that are equal in
# exact arithmetic (e.g. 0.99 - 0.95 vs 0.84 - 0.80 in two scenes) stay tied
# despite floating-point round-off.
_ROUNDOFF_DECIMALS = 12
# Permutations per chunk (bounds memory at chunk x S x M); the result does not
# depend on it.
_CHUNK = 1000
# Slack for comparing |rho_perm| with |rho_obs|: a permutation that merely
# reproduces the observed statistic must count as "at least as extreme".
_TIE_EPS = 1e-12


@dataclass(frozen=True)
class Association:
    """Association statistics of one pair of axes (floats; NaN when undefined).

    Attributes:
        rho: Spearman rho over all cells.
        rho_centred: Spearman rho after within-scene centring.
        p_centred: two-sided within-scene permutation p-value of rho_centred.
        tau_mean, tau_sd: mean and sd (ddof=0) of within-scene Kendall tau-b.
        n_tau_scenes: number of scenes with a defined tau.
        n_perm, seed: the permutation settings used.
    """

    rho: float
    rho_centred: float
    p_centred: float
    tau_mean: float
    tau_sd: float
    n_tau_scenes: int
    n_perm: int
    seed: int


def _spearman(x: np.ndarray, y: np.ndarray) -> float:
    from scipy.stats import spearmanr  # here: importing scipy.stats costs every command ~0.6 s

    if x.size < 2 or np.all(x == x[0]) or np.all(y == y[0]):
        return float("nan")
    return float(spearmanr(x, y).statistic)


def _centre(a: np.ndarray) -> np.ndarray:
    return np.round(a - a.mean(axis=1, keepdims=True), _ROUNDOFF_DECIMALS)


def _permutation_p(a_c: np.ndarray, b_c: np.ndarray, rho_obs: float, n_perm: int, seed: int) -> float:
    """Two-sided p of Spearman rho with b's method labels shuffled within scenes.

    Spearman rho is the Pearson correlation of the ranks over all cells.
    Shuffling b within scenes only moves b's cell ranks around (it does not
    change the multiset of values), so the ranks are computed once and each
    permutation costs one dot product.
    """
    n_scenes, n_methods = a_c.shape
    ra = average_ranks(a_c.ravel()).reshape(a_c.shape)
    rb = average_ranks(b_c.ravel()).reshape(b_c.shape)
    ra -= ra.mean()
    rb -= rb.mean()
    denom = np.sqrt((ra * ra).sum() * (rb * rb).sum())
    rng = np.random.default_rng(seed)
    rows = np.arange(n_scenes)[None, :, None]
    extreme = 0
    done = 0
    while done < n_perm:
        n = min(_CHUNK, n_perm - done)
        order = np.broadcast_to(np.arange(n_methods), (n, n_scenes, n_methods)).copy()
        rng.permuted(order, axis=2, out=order)
        rho_perm = (rb[rows, order] * ra).sum(axis=(1, 2)) / denom
        extreme += int(np.count_nonzero(np.abs(rho_perm) >= abs(rho_obs) - _TIE_EPS))
        done += n
    return (1.0 + extreme) / (1.0 + n_perm)


def _kendall_within_scenes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    from scipy.stats import kendalltau

    taus = []
    for x, y in zip(a, b):
        if x.size < 2 or np.all(x == x[0]) or np.all(y == y[0]):
            continue
        taus.append(kendalltau(x, y).statistic)
    return np.asarray(taus, dtype=np.float64)


def spearman_association(a, b, n_perm: int = N_PERM, seed: int = 0) -> Association:
    """Association of two axes over a scenes x methods grid.

    Args:
        a, b: float arrays (S, M) of two axes (or any two per-cell quantities,
            e.g. iou_drop vs s_sem), finite.
        n_perm: permutations for ``p_centred`` (>= 1).
        seed: seed of the ``numpy.random.default_rng`` generator used for the
            permutations.

    Returns:
        :class:`Association`; a statistic is NaN where undefined (fewer than
        two cells, or an input constant over the cells it is computed on).
    """
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.ndim != 2 or x.shape != y.shape:
        raise ValueError(f"a and b must be (scenes, methods) arrays of one shape, got {x.shape} and {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("association inputs must be finite")
    if n_perm < 1:
        raise ValueError("n_perm must be at least 1")
    with warnings.catch_warnings():
        # Constant inputs are detected and reported as NaN above; scipy's
        # warning for them would only be noise.
        from scipy.stats import ConstantInputWarning

        warnings.simplefilter("ignore", ConstantInputWarning)
        rho = _spearman(x.ravel(), y.ravel())
        xc, yc = _centre(x), _centre(y)
        rho_c = _spearman(xc.ravel(), yc.ravel())
        p_c = float("nan") if np.isnan(rho_c) else _permutation_p(xc, yc, rho_c, n_perm, seed)
        taus = _kendall_within_scenes(x, y)
    return Association(
        rho=rho,
        rho_centred=rho_c,
        p_centred=p_c,
        tau_mean=float(taus.mean()) if taus.size else float("nan"),
        tau_sd=float(taus.std(ddof=0)) if taus.size else float("nan"),
        n_tau_scenes=int(taus.size),
        n_perm=int(n_perm),
        seed=int(seed),
    )


def axis_association(cells: AxisCells, n_perm: int = N_PERM, seed: int = 0) -> dict[str, Association]:
    """:func:`spearman_association` for each pair in :data:`AXIS_PAIRS`.

    Every pair uses the same seed, so each p-value does not depend on which
    other pairs are computed.

    Returns:
        ``{"sem-geo": Association, "sem-str": ..., "geo-str": ...}``.
    """
    return {
        pair: spearman_association(getattr(cells, p), getattr(cells, q), n_perm=n_perm, seed=seed)
        for pair, (p, q) in AXIS_PAIRS.items()
    }
