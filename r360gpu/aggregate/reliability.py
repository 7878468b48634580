"""Reliability of a ranking across scenes (Supp. "How Much of the Ranking Is Significant?").

Reproduces tab:supp_reliability from the per-scene RQS table tab:supp_rqs:

* ``mean``: scene-macro mean RQS (each scene weighted equally);
* ``sd``: sample standard deviation over scenes, ``ddof=1`` (ddof=0 does not
  reproduce the printed values, e.g. 0.167 instead of 0.175 for GC);
* ``min``/``max``: the range over scenes;
* ``ci_low``/``ci_high``: normal-approximation interval
  ``mean +- z_(1+level)/2 * sd / sqrt(S)`` with z = 1.95996 for 95%.  This is
  the reading that reproduces all six printed intervals exactly; the
  t-interval (e.g. [0.547, 0.782] for GC) and the bootstrap percentile
  interval (e.g. [0.563, 0.760]) do not;
* ``p_beats_best``: paired scene-level bootstrap.  Each resample draws S
  scenes with replacement, the same scenes for every method; the value is the
  fraction of resamples in which the method's scene-macro mean RQS is strictly
  greater than that of the best method (highest mean RQS).
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
        ci_level: coverage of the normal-approximation interval, in (0, 1).

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
    # here, not at the top: scipy.special costs every command ~0.15 s to import, and only
    # runs of two scenes or more need the normal quantile (scipy.stats would cost ~0.6 s)
    from scipy.special import ndtri

    half = ndtri(0.5 + ci_level / 2.0) * sd / np.sqrt(n_scenes)
    best = int(np.argmax(mean))

    rng = np.random.default_rng(seed)
    wins = np.zeros(n_methods, dtype=np.int64)
    done = 0
    while done < n_boot:
        n = min(_CHUNK, n_boot - done)
        idx = rng.integers(0, n_scenes, size=(n, n_scenes))
        boot_means = r[idx].mean(axis=1)  # (n, M)
        wins += (boot_means > boot_means[:, [best]]).sum(axis=0)
        done += n
    p = wins / float(n_boot)
    p[best] = np.nan

    return Reliability(
        mean=mean, sd=sd, min=r.min(axis=0), max=r.max(axis=0),
        ci_low=mean - half, ci_high=mean + half,
        p_beats_best=p, best=best, n_boot=int(n_boot), seed=int(seed), ci_level=float(ci_level),
    )
