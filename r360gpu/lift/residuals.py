"""Residuals on Gaussians: which of a method's Gaussians carry the evidence that the object is still there.

For one edited scene (a splat method) and the views where an axis flags
evidence (:func:`flagged_views`), a Gaussian's residual is its compositing
weight inside the target region M of the flagged views over its total
weight in every scored view::

    residual[g] = sum over flagged views, pixels in M of alpha T
                  / sum over all views, all pixels of alpha T

(0 where the Gaussian is never blended).  One lifting pass
(:class:`~r360gpu.lift.device.MaskLifter`) with M in the flagged views and an
empty mask in the others gives both sums.  A Gaussian that fills the target
region exactly where the probes see the object has residual near 1; the
background, seen mostly elsewhere, near 0.
"""
from __future__ import annotations

from ..protocol import AXES

import os
from pathlib import Path

import numpy as np

from .device import MaskLifter

#: A view is evidence when its single-view s_sem, acc_depth or s_str falls below this.
FLAG_BELOW = 0.5


def flagged_views(records, xis=(0.3,)) -> list[str]:
    """Views (names) of a method's per-view records (:class:`~r360gpu.metrics.record.ViewRecord`
    or their dicts) where some axis flags evidence: the semantic probe fires in M on I_post
    (s_sem), the depth in M stays pre's (acc_depth), or the structure differs (s_str), each below
    :data:`FLAG_BELOW` on that view alone."""
    from ..aggregate.results import method_axes
    from ..metrics.record import ViewRecord

    out = []
    for r in records:
        rec = ViewRecord.from_dict(r) if isinstance(r, dict) else r
        axes = method_axes([rec], xis=xis)
        if any(axes.get(k) is not None and axes[k] < FLAG_BELOW for k in AXES):
            out.append(rec.view)
    return out


def residuals(gaussians, cameras, masks, flagged, *, ctx=None, options=None) -> np.ndarray:
    """(N,) float64 residual of each of ``gaussians`` (N) (see the module docstring).

    cameras: the scored views' cameras; masks: their (H, W) bool target masks
    (or float32 wgpu buffers); flagged: the names (``camera.name``) of the
    views that flag evidence.
    """
    flagged = set(flagged)
    lifter = MaskLifter(gaussians, ctx=ctx, options=options)
    try:
        lifter.reset()
        for cam, m in zip(cameras, masks):
            if cam.name in flagged:
                lifter.add_view(cam, m)
            else:
                lifter.add_view(cam, np.zeros((cam.height, cam.width), np.float32))
        w_in, w_out = lifter.weights()
    finally:
        lifter.release()
    total = w_in + w_out
    return np.divide(w_in, total, out=np.zeros_like(total), where=total > 0)


def top_residuals(residual: np.ndarray, k: int) -> np.ndarray:
    """(min(k, N),) int64 indices of the highest residuals, highest first (ties: lower index first)."""
    r = np.asarray(residual, np.float64)
    order = np.lexsort((np.arange(len(r)), -r))
    return order[: max(0, int(k))].astype(np.int64)


def write_residual_ply(path: str | os.PathLike, gaussians, residual: np.ndarray) -> Path:
    """Write ``gaussians`` as an INRIA 3DGS PLY with a float ``residual`` vertex property (SuperSplat
    and r360gpu's viewer can colour by it)."""
    from numpy.lib import recfunctions

    from ..io.inria_ply import save_ply
    from ..io.ply import read_ply, write_ply

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    r = np.asarray(residual, np.float32)
    if r.shape != (gaussians.n,):
        raise ValueError(f"residual has shape {r.shape}, the scene {gaussians.n} Gaussians")
    save_ply(path, gaussians)
    vert = read_ply(path).arrays["vertex"]
    vert = recfunctions.append_fields(vert, "residual", r, dtypes="<f4", usemask=False)
    write_ply(path, [("vertex", vert)])
    return path
