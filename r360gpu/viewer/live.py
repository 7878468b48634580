"""Measurements at the current viewpoint, on the GPU: |dD| binning + GHT, and the live geometric axis.

Both reuse r360gpu's own kernels and metric code on the viewer's device
images (no host copy of the depths): :func:`delta_stats` runs the first pass
of :mod:`r360gpu.kernels.depth_change` and GHT (:mod:`r360gpu.metrics.ght`)
to place the overlays' threshold; :func:`live_axis` runs
:func:`r360gpu.metrics.geometric.acc_depth_view` for ``acc_depth`` at this
viewpoint against a target mask of the same size.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from r360gpu.kernels import depth_change as kernel
from r360gpu.metrics.geometric import GeometricView, GhtParams, acc_depth_view
from r360gpu.metrics.ght import ght, threshold_value

from .layers import PlaneImage
from .overlays import DeltaStats


def delta_stats(ctx, pre: PlaneImage, post: PlaneImage, ght_params: GhtParams = GhtParams()) -> DeltaStats:
    """Binning and GHT split of |D_pre - D_post| over the whole image (same size required)."""
    if (pre.width, pre.height) != (post.width, post.height):
        raise ValueError(f"pre is {pre.width}x{pre.height} but the scene is {post.width}x{post.height}")
    stage = kernel.delta_histogram(pre.device_depth(), post.device_depth(), ctx=ctx)
    split = ght(stage.hist, **ght_params.as_dict()).threshold
    return DeltaStats(stage.lo, stage.hi, float(stage.scale), float(split),
                      float(threshold_value(split, stage.lo, stage.hi, kernel.N_BINS)))


def stats_of(view: GeometricView) -> DeltaStats:
    """The :class:`DeltaStats` behind a float-mode :class:`GeometricView`."""
    return DeltaStats(view.lo, view.hi, float(kernel.bin_scale(view.lo, view.hi)), float(view.split), float(view.threshold))


@dataclass(frozen=True)
class LiveAxis:
    """The geometric axis at the current viewpoint.

    acc_depth: |changed ∩ M| / |M| (None when the mask is empty);
    threshold: the GHT threshold t_depth (depth units); n_mask, n_changed_in_mask: pixel
    counts; changed_fraction: changed pixels over the whole image;
    mask_kind: "evaluation" (the view's target mask) or "projected"
    (the estimated 3D target's silhouette); width, height: resolution.
    """

    acc_depth: float | None
    threshold: float
    n_mask: int
    n_changed_in_mask: int
    changed_fraction: float
    mask_kind: str
    width: int
    height: int
    stats: DeltaStats


def live_axis(ctx, pre: PlaneImage, post: PlaneImage, mask: np.ndarray, mask_kind: str,
              ght_params: GhtParams = GhtParams()) -> LiveAxis:
    """acc_depth of ``post`` against ``pre`` with target ``mask`` (H, W) bool at the images' size."""
    view = acc_depth_view(pre.device_depth(), post.device_depth(), mask, ght_params=ght_params, ctx=ctx)
    frac = float(view.changed.mean()) if view.changed.size else 0.0
    return LiveAxis(view.acc_depth, float(view.threshold), int(view.n_mask), int(view.n_changed_in_mask), frac,
                    mask_kind, post.width, post.height, stats_of(view))


class LiveMeter:
    """The live geometric axis of the app's shown methods at the current viewpoint, measured once
    per resting pose.

    live: {scene: LiveAxis}; note: why nothing was measured (empty when something was);
    stale: the camera moved since the values were measured.
    """

    def __init__(self, app):
        self.app = app
        self.live: dict[str, LiveAxis] = {}
        self.note = ""
        self.stale = False
        self._key = None

    def update(self, cam, view: str | None) -> None:
        """Measure acc_depth of each shown non-pre scene at this viewpoint (once per still pose)."""
        from .layers import camera_key

        app = self.app
        key = (camera_key(cam), view, app.state.shown())
        if key == self._key:
            self.stale = False
            return
        self._key = key
        self.live = {}
        self.stale = False
        targets = [n for n in dict.fromkeys(app.state.shown()) if n != "pre"]
        if not targets:
            self.note = "pre vs pre: show a method to measure it"
            return
        pre_layer = app.layers["pre"]
        if view is not None and app.view_cameras[app.views.index(view)] is not None:
            mcam = app.view_cameras[app.views.index(view)]
            kind = "evaluation"
        elif view is not None:
            mcam, kind = cam, "evaluation"
        else:
            mcam, kind = cam, "projected"
        if not pre_layer.has_depth:
            self.note = "pre has no depth (renders without a depth folder): no geometric axis"
            return
        pre = pre_layer.image(mcam, view)
        if pre is None:
            self.note = "pre has no image here (renders source off the evaluation views)"
            return
        if kind == "evaluation":
            mask = app.pictures.mask_of(view, pre.width, pre.height)
        else:
            mask = app.target.projected_mask(mcam, pre)
            if mask is None:
                self.note = "no target estimate: the live axis needs a mask off the evaluation views"
                return
        self.note = ""
        for name in targets:
            if not app.layers[name].has_depth:
                continue
            img = app.layers[name].image(mcam, view)
            if img is None or img.size != pre.size:
                continue
            self.live[name] = live_axis(app.ctx, pre, img, mask, kind)
