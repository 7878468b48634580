"""Per-axis ranks of methods and their summaries (eq. ``eq:avg_rank``, Supp. tab:supp_rank_agg).

Rank 1 is the best method; every axis is oriented so that higher is better;
tied values share their average rank (``scipy.stats.rankdata(method="average")``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Values are compared after rounding to this many decimals unless the caller
# asks for fewer: round-off (e.g. 0.1 + 0.2 vs 0.3 from two pooling orders)
# must not split a tie.
_ROUNDOFF_DECIMALS = 12


def axis_ranks(values, decimals: int | None = None) -> np.ndarray:
    """Rank methods on one axis: 1 = highest value, ties get their average rank.

    Args:
        values: 1-D array-like (M,) of axis values, higher is better, finite.
        decimals: compare values after rounding to this many decimals (e.g. 3
            to rank "as printed"); None compares at full precision (up to
            round-off at 1e-12).

    Returns:
        float64 array (M,) of ranks in [1, M]; a tie of k methods at positions
        r..r+k-1 gets (2r+k-1)/2 each.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"values must be 1-D (methods,), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("cannot rank non-finite axis values")
    x = np.round(x, _ROUNDOFF_DECIMALS if decimals is None else decimals)
    return average_ranks(-x)


def average_ranks(x: np.ndarray) -> np.ndarray:
    """Ranks 1..n of a 1-D float array, ascending, ties sharing their average
    rank: ``scipy.stats.rankdata(x, method="average")`` (tested equal), kept
    here because importing scipy.stats costs every command about 0.6 s."""
    x = np.asarray(x, np.float64)
    order = np.argsort(x, kind="mergesort")
    s = x[order]
    first = np.r_[True, s[1:] != s[:-1]]  # first of each run of equal values
    bounds = np.flatnonzero(np.r_[first, True])  # run k spans sorted positions bounds[k]..bounds[k+1]-1
    ranks = np.empty(x.size, np.float64)
    ranks[order] = ((bounds[:-1] + bounds[1:] + 1) / 2.0)[np.cumsum(first) - 1]
    return ranks


@dataclass(frozen=True)
class RankSummary:
    """Ranks of M methods on the three axes and their summaries.

    Attributes:
        ranks: float64 (M, 3), per-axis ranks in ``AXES`` order.
        avg_rank: float64 (M,), mean of the three ranks (AvgRank, eq:avg_rank).
        med_rank: float64 (M,), median of the three ranks (MedRank).
        worst_rank: float64 (M,), the largest (worst) single-axis rank.
    """

    ranks: np.ndarray
    avg_rank: np.ndarray
    med_rank: np.ndarray
    worst_rank: np.ndarray


def rank_summary(axes, decimals: int | None = None) -> RankSummary:
    """Rank methods on each axis and summarise the ranks per method.

    Args:
        axes: float array (M, K) of dataset-level axis values (K = 3 for
            s_sem, s_geo, s_str), higher is better.
        decimals: passed to :func:`axis_ranks`.

    Returns:
        :class:`RankSummary` with arrays over the M methods.
    """
    a = np.asarray(axes, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"axes must have shape (methods, axes), got {a.shape}")
    ranks = np.stack([axis_ranks(a[:, k], decimals) for k in range(a.shape[1])], axis=1)
    return RankSummary(
        ranks=ranks,
        avg_rank=ranks.mean(axis=1),
        med_rank=np.median(ranks, axis=1),
        worst_rank=ranks.max(axis=1),
    )
