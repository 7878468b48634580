"""Residuals on Gaussians: which of a method's Gaussians carry the evidence that the object is still there.

For one edited scene (a splat method) and the views where an axis flags
evidence (:func:`flagged_views`), a Gaussian's residual is its compositing
weight inside the target region M of the flagged views, where it stands in
the space the object occupied, over its total weight in every scored view::

    residual[g] = sum over flagged views v of  in_front[g, v] * (sum over pixels in M of alpha T)
                  / sum over all views, all pixels of alpha T

(0 where the Gaussian is never blended).  ``in_front[g, v]`` says the
Gaussian lies in front of the surface behind the object (the reference scene
rendered at v when there is one, the capture after the removal; else pre
without the target: :func:`surface_depth`, :func:`depth_behind`): its centre's depth plus
:data:`GATE_SIGMAS` standard deviations along the viewing ray is nearer than
that surface at its centre's pixel.  Why: every view sees the hole's
completion (the floor, the wall the object hid) only through M, exactly as it
sees a remnant, so M alone ranks the completion with the residue; the
completion lies on the surface behind the object, a remnant in front of it.
Where pre has nothing behind (alpha < 0.5 there), or no depth behind is given,
every Gaussian counts (the residual is then M's share alone).

One lifting pass (:class:`~r360gpu.lift.device.MaskLifter`) per flagged view
gives that view's weights; the others add to the totals only.  A Gaussian
that fills the target region exactly where the probes see the object has
residual near 1; the background, seen mostly elsewhere or behind, near 0.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..protocol import AXES
from .device import MaskLifter

#: A view is evidence when its single-view s_sem, acc_depth or s_str falls below this.
FLAG_BELOW = 0.5


def flagged_views(view_axes: dict[str, dict]) -> list[str]:
    """The views of ``view_axes`` ({view: that view's axes alone}, as
    `r360gpu.aggregate.results.per_view_axes` gives them for a method's records) where some
    axis flags evidence: the semantic probe fires in M on I_post (s_sem), the depth in M stays pre's
    (acc_depth), or the structure differs (s_str), each below `FLAG_BELOW` on that view alone."""
    return [v for v, axes in view_axes.items()
            if any(axes.get(k) is not None and axes[k] < FLAG_BELOW for k in AXES)]


#: A Gaussian whose centre lies within this many standard deviations (along the viewing ray) of the
#: surface behind the object is part of that surface (3 sigma: 99.7% of a Gaussian's mass).
GATE_SIGMAS = 3.0
#: Where pre without the target covers a pixel less than this, nothing is behind the object there
#: (its median depth, where the transmittance crosses one half, is undefined).
BEHIND_ALPHA = 0.5


def depth_behind(pre, target, cameras, *, ctx=None, options=None, frame=None) -> list:
    """[(H, W) float32] per camera: `surface_depth` of ``pre`` (Gaussians, in ``frame``) without
    ``target`` ((N,) bool), what pre has behind the object."""
    return surface_depth(pre.subset(~np.asarray(target, bool)), cameras, ctx=ctx, options=options, frame=frame)


def surface_depth(gaussians, cameras, *, ctx=None, options=None, frame=None) -> list:
    """[(H, W) float32] per camera: the median depth of ``gaussians`` (a scene without the object: pre
    without the target, or the reference), in the cameras' units whatever the scene's ``frame``
    (`Frame`; None: the cameras').

    Where that covers less than `BEHIND_ALPHA` (a hole: nothing there, or background the masks
    lifted with the object because every view saw it only through M), the depth of the nearest pixel
    that has a surface, as a completion continues its surroundings; +inf when no pixel has one.
    """
    from scipy import ndimage

    from ..io.frames import depth_in_cameras, in_frame
    from ..render import Renderer

    r = Renderer(gaussians, ctx=ctx, options=options)
    out = []
    try:
        for cam in cameras:
            img = r.render(in_frame(frame, cam))
            median = depth_in_cameras(frame, img.median_depth)
            hole = ~((img.alpha >= BEHIND_ALPHA) & np.isfinite(median))
            depth = np.full(hole.shape, np.inf, np.float32)
            if not hole.all():
                near = ndimage.distance_transform_edt(hole, return_distances=False, return_indices=True)
                depth = median[near[0], near[1]].astype(np.float32)
            out.append(depth)
    finally:
        r.release()
    return out


def in_front(gaussians, camera, behind: np.ndarray, *, frame=None) -> np.ndarray:
    """(N,) bool: each Gaussian's centre depth plus `GATE_SIGMAS` standard deviations along the
    ray from ``camera`` is nearer than ``behind`` (H, W, in the cameras' units) at its centre's pixel;
    True where the centre falls outside the image or behind the camera (no surface to compare with).
    frame: the Gaussians' world frame (None: the cameras')."""
    from ..io.frames import depth_in_cameras, in_frame
    from ..io.rotation import quat_to_rotmat

    camera = in_frame(frame, camera)

    means = np.asarray(gaussians.means, np.float64)
    uv, z = camera.project(means)
    ray = means - camera.center
    ray /= np.maximum(np.linalg.norm(ray, axis=1, keepdims=True), 1e-12)
    rot = quat_to_rotmat(gaussians.quats)
    # sigma along the ray: |S R^T d| (the covariance is R S^2 R^T)
    sigma = np.linalg.norm(np.einsum("nji,nj->ni", rot, ray) * np.asarray(gaussians.scales, np.float64), axis=1)
    h, w = behind.shape
    inside = np.isfinite(uv).all(1)
    inside[inside] = (uv[inside, 0] >= 0) & (uv[inside, 0] < w) & (uv[inside, 1] >= 0) & (uv[inside, 1] < h)
    out = np.ones(len(means), bool)
    px = np.floor(uv[inside]).astype(np.int64)
    out[inside] = depth_in_cameras(frame, z[inside] + GATE_SIGMAS * sigma[inside]) < behind[px[:, 1], px[:, 0]]
    return out


def residuals(gaussians, cameras, masks, flagged, *, behind=None, ctx=None, options=None,
              frame=None) -> np.ndarray:
    """(N,) float64 residual of each of ``gaussians`` (N) (see the module docstring).

    cameras: the scored views' cameras; masks: their (H, W) bool target masks
    (or float32 wgpu buffers); flagged: the names (``camera.name``) of the
    views that flag evidence; behind: None, or per camera the (H, W) depth of
    what pre has behind the object (`depth_behind`; +inf where nothing), in the cameras'
    units; frame: the Gaussians' world frame (None: the cameras'), applied to every camera.
    """
    from ..io.frames import in_frame

    flagged = set(flagged)
    if behind is not None and len(behind) != len(cameras):
        raise ValueError(f"behind has {len(behind)} depth maps for {len(cameras)} cameras")
    gated = {k for k, cam in enumerate(cameras) if behind is not None and cam.name in flagged}
    lifter = MaskLifter(gaussians, ctx=ctx, options=options)
    try:
        lifter.reset()  # the ungated views in one pass: unflagged ones add to the totals only
        for k, (cam, m) in enumerate(zip(cameras, masks)):
            if k not in gated:
                lifter.add_view(in_frame(frame, cam),
                                m if cam.name in flagged else np.zeros((cam.height, cam.width), np.float32))
        w_in, w_out = lifter.weights()
        total = w_in + w_out
        for k in sorted(gated):  # each view's weights alone, gated by the surface behind the object there
            lifter.reset()
            lifter.add_view(in_frame(frame, cameras[k]), masks[k])
            v_in, v_out = lifter.weights()
            w_in = w_in + v_in * in_front(gaussians, cameras[k], np.asarray(behind[k]), frame=frame)
            total = total + v_in + v_out
    finally:
        lifter.release()
    return np.divide(w_in, total, out=np.zeros_like(total), where=total > 0)


def top_residuals(residual: np.ndarray, k: int) -> np.ndarray:
    """(at most k,) int64 indices of the highest residuals above 0, highest first (ties: lower index
    first).  A Gaussian of residual 0 is in no flagged evidence, so it is never listed: filling
    the list with such Gaussians (in row order) would name Gaussians 0, 1, 2, ... as residuals."""
    r = np.asarray(residual, np.float64)
    order = np.lexsort((np.arange(len(r)), -r))[: max(0, int(k))]
    return order[r[order] > 0].astype(np.int64)


def write_residual_ply(path: str | os.PathLike, gaussians, residual: np.ndarray, *, source=None) -> Path:
    """Write ``gaussians`` as an INRIA 3DGS PLY with a float ``residual`` vertex property (SuperSplat
    and r360gpu's viewer can colour by it).

    The vertices are the rows of the method's file: ``source`` (its path), when it is an INRIA PLY,
    is copied vertex for vertex with every property it has (a ``my_label`` stays); otherwise the
    Gaussians' own properties.  A row the loader dropped (invalid values, `Gaussians.rows`)
    keeps its place with residual NaN (and, when not copied, NaN properties).
    """
    from ..io.inria_ply import RESIDUAL, write_labelled_ply

    path = Path(path)
    write_labelled_ply(path, gaussians, RESIDUAL, np.asarray(residual, np.float32), np.nan, "<f4", source=source)
    return path
