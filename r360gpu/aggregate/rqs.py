"""Removal Quality Score and the per-view -> scene -> overall pooling of axes.

Paper eq. ``eq:rqs`` and Supp. A.4 "Aggregation":

* scene level: per-view values are averaged per scene (:func:`scene_axis`),
  and the scene RQS is the geometric mean of the three scene axes;
* overall: all views of all scenes are pooled per axis, which equals the
  view-weighted mean of the scene axes (:func:`pool_over_scenes` with
  ``n_views``); RQS is then computed from the three pooled axes;
* the scene-macro mean (every scene weighted equally; ``n_views=None``) is a
  different, separately labelled statistic.
"""
from __future__ import annotations

import numpy as np


def rqs(s_sem, s_geo, s_str) -> np.ndarray | float:
    """Removal Quality Score ``(s_sem * s_geo * s_str) ** (1/3)`` (eq. ``eq:rqs``).

    Args:
        s_sem, s_geo, s_str: the three axes; scalars or arrays of any mutually
            broadcastable shapes, values in [0, 1].

    Returns:
        float64 array of the broadcast shape (a Python float for scalar input).
        Any axis equal to 0 gives exactly 0.  NaN marks an undefined axis (no
        valid view) and propagates: the score is NaN, even if another axis is
        0, because an unmeasured axis makes the score undefined rather than
        bad.

    Raises:
        ValueError: a non-NaN value lies outside [0, 1].
    """
    a, b, c = (np.asarray(x, dtype=np.float64) for x in (s_sem, s_geo, s_str))
    for name, x in (("s_sem", a), ("s_geo", b), ("s_str", c)):
        bad = ~np.isnan(x) & ((x < 0.0) | (x > 1.0))
        if np.any(bad):
            raise ValueError(f"{name} must lie in [0, 1]; got {x[bad].ravel()[0]!r}")
    # cbrt rather than ** (1/3): 1/3 is not representable, so the power can be
    # an ulp off even for exact cubes; cbrt gives rqs(x, x, x) == x for them.
    out = np.cbrt(a * b * c)
    return float(out) if out.ndim == 0 else out


def scene_axis(per_view) -> float:
    """Scene-level axis value: the mean of the per-view values of one scene.

    Args:
        per_view: 1-D array-like (V,) of per-view values in [0, 1].  NaN marks
            a view excluded from this axis (e.g. ``acc_depth`` on a view whose
            target mask is empty) and is left out of the mean.

    Returns:
        The mean over the valid views, or NaN when no view is valid.
    """
    x = np.asarray(per_view, dtype=np.float64).ravel()
    valid = x[~np.isnan(x)]
    return float(valid.mean()) if valid.size else float("nan")


def pool_over_scenes(values, n_views=None) -> np.ndarray:
    """Pool scene-level values over scenes (axis 0).

    Args:
        values: float array (S, ...) of scene-level values (e.g. (S, M) or
            (S, M, 3)).
        n_views: None, or positive counts broadcastable to ``values`` (e.g.
            (S, M) for (S, M) values; (S, M) is also accepted for (S, M, 3)
            values and then applies to every axis).  With counts, the result is
            the view-weighted mean, which equals pooling every view of every
            scene; without, it is the scene-macro mean (each scene weight 1).

    Returns:
        float64 array ``values.shape[1:]``.
    """
    v = np.asarray(values, dtype=np.float64)
    if n_views is None:
        return v.mean(axis=0)
    w = np.asarray(n_views, dtype=np.float64)
    if w.ndim == v.ndim - 1:
        w = w[..., None]
    w = np.broadcast_to(w, v.shape)
    if np.any(w <= 0):
        raise ValueError("n_views must be positive")
    return (w * v).sum(axis=0) / w.sum(axis=0)
