"""Geometric axis: acc_depth per view and over views (paper eq. acc_depth; docs/protocol.md).

``acc_depth^v = |changed ∩ M| / |M|`` with ``changed = dD > xi_depth^v`` and
``xi_depth^v`` from GHT on the 256-bin histogram of dD over the whole image.
The float-depth path runs on the GPU (:mod:`r360gpu.kernels.depth_change`,
where the dD, binning and missing-depth conventions are written down); the
compat modes (``"public"``, ``"public-default"``) apply the public scripts'
missing-depth rule and 8-bit thresholding (:mod:`r360gpu.metrics.compat`) to
the depth arrays given.  A view whose target mask is empty is excluded
(``acc_depth = None``), never scored 0 or 1; the public scripts score it 0,
which :mod:`r360gpu.metrics.compat_public` reproduces on public folders.

Every view also counts ``n_no_depth_in_mask``: the pixels of M with no depth
after removal (D_post missing: not finite or <= 0), a see-through hole.  dD is
0 there by the missing-depth rule, so acc_depth counts such a pixel as
unchanged; the count says how much of M that is (in every mode; it changes
no other value).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..kernels import depth_change as kernel
from ..protocol import GHT_KAPPA, GHT_NU, GHT_OMEGA, GHT_TAU
from .compat import check_compat, public_changed, public_delta
from .ght import ght, threshold_value


@dataclass(frozen=True)
class GhtParams:
    """Barron's GHT parameters; defaults are the Remove360 reference values."""

    nu: float = GHT_NU
    tau: float = GHT_TAU
    kappa: float = GHT_KAPPA
    omega: float = GHT_OMEGA

    def as_dict(self) -> dict:
        return {"nu": self.nu, "tau": self.tau, "kappa": self.kappa, "omega": self.omega}


@dataclass
class GeometricView:
    """Geometric measurement of one view.

    acc_depth: fraction of target pixels that changed, or None when excluded.
    excluded: True when the target mask is empty (the view is not scored).
    threshold: xi_depth in depth units (float mode) or the 8-bit gray level
        below which a pixel counts as changed (compat mode).
    split: the GHT split position in bin units.
    lo, hi: range of dD spanned by the histogram (float mode; compat: 0, 255).
    hist: (256,) int64 histogram the threshold was chosen on.
    changed: (H, W) bool changed-pixel mask (for heat maps).
    n_mask, n_changed_in_mask: pixel counts behind acc_depth.
    mode: "float", "public" or "public-default".
    n_no_depth_in_mask: pixels of M with no depth after removal (D_post
        missing; a see-through hole, never counted as changed in float mode).
    """

    acc_depth: float | None
    excluded: bool
    threshold: float
    split: float
    lo: float
    hi: float
    hist: np.ndarray
    changed: np.ndarray
    n_mask: int
    n_changed_in_mask: int
    mode: str
    n_no_depth_in_mask: int = 0

    def summary(self) -> dict:
        """JSON-ready scalars (no images)."""
        return {
            "acc_depth": self.acc_depth,
            "excluded": self.excluded,
            "threshold": self.threshold,
            "split": self.split,
            "lo": self.lo,
            "hi": self.hi,
            "n_mask": self.n_mask,
            "n_changed_in_mask": self.n_changed_in_mask,
            "mode": self.mode,
            "n_no_depth_in_mask": self.n_no_depth_in_mask,
        }


def acc_depth_view(
    d_pre,
    d_post,
    mask,
    *,
    compat: bool | str | None = False,
    ght_params: GhtParams = GhtParams(),
    ctx=None,
) -> GeometricView:
    """acc_depth^v of one view.

    d_pre, d_post: float32 (H, W) depth (z-distance), 0 = no coverage; numpy
        arrays or `DeviceDepth` (float mode).
    mask: (H, W) target mask M^v, non-zero = target.
    compat: None/False (paper mode), True or "public", or "public-default":
        the public scripts' missing-depth rule and 8-bit thresholding
        (`public_changed`) on these arrays.  Pass
        uint8 depths read with `read_depth_public`
        to reproduce the scripts exactly.
    """
    m = np.asarray(mask) != 0
    p = ght_params.as_dict()
    mode = check_compat(compat)
    if mode is not None:
        if isinstance(d_pre, kernel.DeviceDepth) or isinstance(d_post, kernel.DeviceDepth):
            raise InputError("compat mode needs host depth arrays (it reproduces a PNG round trip)")
        delta = public_delta(d_pre, d_post)
        if m.shape != delta.shape:
            raise InputError(f"target mask is {m.shape[0]}x{m.shape[1]} but the depth images are {delta.shape[0]}x{delta.shape[1]} (H x W)")
        res = public_changed(delta, mode, **p)
        n_mask = int(m.sum())
        n_in = int((res.changed & m).sum())
        return _view(n_in, n_mask, float(res.threshold), float(res.threshold), 0.0, 255.0, res.hist, res.changed, mode,
                     _no_depth_in_mask(d_post, m))
    stage = kernel.delta_histogram(d_pre, d_post, ctx=ctx)
    split = ght(stage.hist, **p).threshold
    res = kernel.changed_in_mask(stage, m, split, ctx=ctx)
    xi = threshold_value(split, stage.lo, stage.hi, kernel.N_BINS)
    return _view(res.n_changed_in_mask, res.n_mask, xi, split, stage.lo, stage.hi, stage.hist, res.changed, "float",
                 res.n_no_depth_in_mask)


def acc_depth_views(
    d_pre,
    d_posts,
    mask,
    *,
    compat: bool = False,
    ght_params: GhtParams = GhtParams(),
    ctx=None,
) -> list[GeometricView]:
    """:func:`acc_depth_view` of one D_pre against several D_post (the methods
    of one view).  Float mode batches the GPU passes of all methods (D_pre and
    the mask uploaded once, three waits in all); the results equal the
    per-method calls."""
    if compat or not len(d_posts):
        return [acc_depth_view(d_pre, d, mask, compat=compat, ght_params=ght_params, ctx=ctx) for d in d_posts]
    m = np.asarray(mask) != 0
    p = ght_params.as_dict()
    stages = kernel.delta_histograms(d_pre, d_posts, ctx=ctx)
    splits = [ght(st.hist, **p).threshold for st in stages]
    res = kernel.changed_in_masks(stages, m, splits, ctx=ctx)
    return [
        _view(r.n_changed_in_mask, r.n_mask, threshold_value(t, st.lo, st.hi, kernel.N_BINS), t, st.lo, st.hi,
              st.hist, r.changed, "float", r.n_no_depth_in_mask)
        for st, t, r in zip(stages, splits, res)
    ]


def _no_depth_in_mask(d_post, m: np.ndarray) -> int:
    """Pixels of ``m`` where the host depth ``d_post`` is missing (the kernel's rule)."""
    return int(np.count_nonzero(kernel.no_depth(d_post) & m))


def _view(n_in, n_mask, threshold, split, lo, hi, hist, changed, mode, n_no_depth=0) -> GeometricView:
    excluded = n_mask == 0
    acc = None if excluded else n_in / n_mask
    return GeometricView(acc, excluded, threshold, split, lo, hi, np.asarray(hist, np.int64), changed, n_mask, n_in, mode,
                         int(n_no_depth))


def acc_depth(views: list[GeometricView]) -> tuple[float | None, int]:
    """Mean acc_depth^v over the scored views, and the number of excluded views.

    Returns (None, n) when every view is excluded.
    """
    scored = [v.acc_depth for v in views if not v.excluded]
    excluded = len(views) - len(scored)
    return (float(np.mean(scored)) if scored else None, excluded)
