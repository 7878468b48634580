"""Reliability of a ranking across scenes (Supp. "How Much of the Ranking Is Significant?").

Reproduces tab:supp_reliability from the per-scene RQS table tab:supp_rqs:

* ``mean``: scene-macro mean RQS (each scene weighted equally);
* ``sd``: sample standard deviation over scenes, ``ddof=1`` (ddof=0 does not
  reproduce the printed values, e.g. 0.167 instead of 0.175 for GC);
* ``min``/``max``: the range over scenes;
* ``ci_low``/``ci_high``: the paired bootstrap's percentile interval of the
  scene-macro mean RQS: the (1 - level)/2 and (1 + level)/2 quantiles of the
  resampled means.  A mean of scenes cannot leave the scenes' range, so the
  interval lies within [min, max] and never outside [0, 1] for a score in
  [0, 1], however few the scenes.  The paper prints the normal approximation
  ``mean +- 1.96 sd / sqrt(S)`` instead (reproduced from ``mean`` and ``sd`` in
  tests/test_aggregate_reliability.py); with 2 scenes that interval falls below
  0 (e.g. [-0.135, 0.416]) for a score that cannot;
* ``p_beats_best``: paired scene-level bootstrap.  Each resample draws S
  scenes with replacement, the same scenes for every method; the value is the
  fraction of resamples in which the method's scene-macro mean RQS is strictly
  greater than that of the best method (highest mean RQS).

The interval and the probability come from the same resamples, so one seed
fixes both.  Below `r360gpu.protocol.MIN_SCENES_TO_RANK` scenes the
tables leave both out (``aggregate_tables``); this function computes them for
any S >= 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..protocol import CI_LEVEL, N_BOOT

# Resamples per chunk: bounds memory at chunk x S x M floats for large grids.
# Chunking does not change the numbers (the generator's stream is consumed
# in the same order).
_CHUNK = 2000


@dataclass(frozen=True)
class Reliability:
    """Per-method reliability statistics over S scenes.

    Attributes:
        mean, sd, min, max, ci_low, ci_high: float64 arrays (M,).
        p_beats_best: float64 (M,); NaN for the best method itself.
        best: index of the best method (highest mean; the first one listed
            wins a tie).
        n_boot, seed, ci_level: the settings used.
    """

    mean: np.ndarray
    sd: np.ndarray
    min: np.ndarray
    max: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    p_beats_best: np.ndarray
    best: int
    n_boot: int
    seed: int
    ci_level: float


def reliability(scene_rqs, n_boot: int = N_BOOT, seed: int = 0, ci_level: float = CI_LEVEL) -> Reliability:
    """Scene-macro statistics of per-scene RQS and a paired bootstrap against the best method.

    Args:
        scene_rqs: float array (S, M), RQS of each method on each scene, S >= 2.
        n_boot: number of bootstrap resamples (>= 1).
        seed: seed of the ``numpy.random.default_rng`` generator; the same
            seed gives the same result.
        ci_level: coverage of the bootstrap percentile interval, in (0, 1).

    Returns:
        :class:`Reliability`.
    """
    r = np.asarray(scene_rqs, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] < 1:
        raise ValueError(f"scene_rqs must have shape (scenes, methods), got {r.shape}")
    n_scenes, n_methods = r.shape
    if n_scenes < 2:
        raise ValueError("reliability needs at least two scenes")
    if not np.all(np.isfinite(r)):
        raise ValueError("scene_rqs contains non-finite values")
    if n_boot < 1:
        raise ValueError("n_boot must be at least 1")
    if not 0.0 < ci_level < 1.0:
        raise ValueError("ci_level must lie in (0, 1)")

    mean = r.mean(axis=0)
    sd = r.std(axis=0, ddof=1)
    best = int(np.argmax(mean))

    rng = np.random.default_rng(seed)
    wins = np.zeros(n_methods, dtype=np.int64)
    boot_means = np.empty((n_boot, n_methods))  # kept for the percentile interval
    done = 0
    while done < n_boot:
        n = min(_CHUNK, n_boot - done)
        idx = rng.integers(0, n_scenes, size=(n, n_scenes))
        chunk = boot_means[done:done + n] = r[idx].mean(axis=1)  # (n, M)
        wins += (chunk > chunk[:, [best]]).sum(axis=0)
        done += n
    p = wins / float(n_boot)
    p[best] = np.nan
    tail = (1.0 - ci_level) / 2.0
    low, high = np.quantile(boot_means, [tail, 1.0 - tail], axis=0)
    # The clip only undoes rounding: a resampled mean of equal scenes may differ from them by an ulp.
    lo, hi = r.min(axis=0), r.max(axis=0)

    return Reliability(
        mean=mean, sd=sd, min=lo, max=hi,
        ci_low=np.clip(low, lo, hi), ci_high=np.clip(high, lo, hi),
        p_beats_best=p, best=best, n_boot=int(n_boot), seed=int(seed), ci_level=float(ci_level),
    )
