"""The target object in 3D, from pre's Gaussians and the evaluation views' target masks.

A Gaussian belongs to the target when its centre projects inside the target
mask in most of the evaluation views that see it (a visual-hull vote):
centres behind the object fall inside the mask from one side but outside
from others, so they are voted out.  The target's centre (median of the
voted centres) and radius (90th percentile distance) drive "focus on the
target"; its Gaussians, rendered alone, give a target mask at viewpoints
that are not evaluation views (:func:`projected_mask`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from r360gpu.io.camera import Camera

#: A centre is target when inside the mask in at least this fraction of the views that see it...
VOTE_FRACTION = 0.6
#: ...and inside the mask in at least this many views (1 when there is a single view).
MIN_VOTES = 2
#: At most this many views vote (evenly spaced), to bound the start-up time.
MAX_VOTING_VIEWS = 24
#: A target pixel is visible when the target's depth is at most this factor of pre's depth.
VISIBLE_TOLERANCE = 1.05


@dataclass(frozen=True)
class Target:
    """The estimated target: ``indices`` (int64) of pre's Gaussians, ``centre`` (3,), ``radius``."""

    indices: np.ndarray
    centre: np.ndarray
    radius: float


def voting_views(n: int) -> list[int]:
    """Indices of the at most MAX_VOTING_VIEWS views (evenly spaced) out of ``n`` that vote."""
    if n <= 0:
        return []
    return [int(i) for i in np.unique(np.linspace(0, n - 1, min(MAX_VOTING_VIEWS, n)).round().astype(int))]


def estimate_target(means: np.ndarray, cameras: list[Camera], masks: list[np.ndarray]) -> Target | None:
    """Vote pre's Gaussian centres ``means`` (N, 3) into the target (see the module docstring).

    cameras[i] pairs with masks[i], an (H, W) bool target mask at that camera's
    size; the views of :func:`voting_views` vote.  Returns None when no centre
    collects enough votes.
    """
    if len(cameras) != len(masks):
        raise ValueError(f"{len(cameras)} cameras but {len(masks)} masks")
    if not cameras:
        return None
    pick = voting_views(len(cameras))
    p = np.asarray(means, np.float64).reshape(-1, 3)
    seen = np.zeros(len(p), np.int32)
    inside = np.zeros(len(p), np.int32)
    for i in pick:
        cam, m = cameras[i], np.asarray(masks[i], bool)
        uv, z = cam.project(p)
        ok = z > 0
        u = np.floor(np.where(ok, uv[:, 0], -1)).astype(np.int64)
        v = np.floor(np.where(ok, uv[:, 1], -1)).astype(np.int64)
        ok &= (u >= 0) & (v >= 0) & (u < m.shape[1]) & (v < m.shape[0])
        seen += ok
        hit = np.zeros(len(p), bool)
        hit[ok] = m[v[ok], u[ok]]
        inside += hit
    need = min(MIN_VOTES, len(pick))
    sel = (inside >= need) & (inside >= VOTE_FRACTION * np.maximum(seen, 1))
    idx = np.flatnonzero(sel)
    if idx.size == 0:
        return None
    pts = p[idx]
    centre = np.median(pts, axis=0)
    radius = float(np.percentile(np.linalg.norm(pts - centre, axis=1), 90))
    return Target(idx.astype(np.int64), centre, max(radius, 1e-6))


def projected_mask(target_alpha: np.ndarray, target_depth: np.ndarray, pre_depth: np.ndarray) -> np.ndarray:
    """The visible target silhouette (H, W) bool at a free viewpoint.

    target_alpha / target_depth: the target's Gaussians rendered alone;
    pre_depth: pre's depth (0 = no coverage).  A pixel is target where the
    target covers it (alpha >= 0.5) and nothing of pre lies clearly in front
    (target depth <= VISIBLE_TOLERANCE x pre depth, or pre has no depth).
    """
    a = np.asarray(target_alpha, np.float32)
    td = np.asarray(target_depth, np.float32)
    pd = np.asarray(pre_depth, np.float32)
    covered = (a >= 0.5) & (td > 0)
    visible = (pd <= 0) | (td <= np.float32(VISIBLE_TOLERANCE) * pd)
    return covered & visible


class SceneTarget:
    """The app's target estimate: made once on first use (pre splat + cameras + masks), then used
    to focus the camera and to give a target mask away from the evaluation views."""

    def __init__(self, app):
        self.app = app
        self.target: Target | None = None
        self.layer = None  # the target's Gaussians alone, as a SplatLayer
        self._done = False

    def ensure(self) -> Target | None:
        """Estimate the 3D target once, None when impossible."""
        from .layers import SplatLayer

        if self._done:
            return self.target
        self._done = True
        app = self.app
        pre = app.layers.get("pre")
        if not isinstance(pre, SplatLayer) or not app.cameras:
            return None
        pairs = [(v, c) for v, c in zip(app.views, app.view_cameras) if c is not None and v in app.bundle.masks]
        pairs = [pairs[i] for i in voting_views(len(pairs))]
        cams = [c for _, c in pairs]
        masks = [app.pictures.mask_of(v, c.width, c.height) for v, c in pairs]
        self.target = estimate_target(pre.gaussians.means, cams, masks)
        if self.target is not None:
            gauss = pre.gaussians.subset(self.target.indices)
            self.layer = SplatLayer.from_gaussians("target", gauss, ctx=app.ctx,
                                                   background=app.bundle.options.background)
        return self.target

    def focus(self) -> None:
        """Point the camera at the target (at the pivot when there is no estimate)."""
        app = self.app
        target = self.ensure()
        if target is not None:
            app.camera.focus(target.centre, target.radius)
        else:
            app.camera.focus(app.camera.pivot, app.scale_length * 0.5)
            app.notify("no target estimate (needs a splat pre scene, cameras and masks): focused on the pivot")

    def projected_mask(self, cam, pre) -> np.ndarray | None:
        """The estimated target's visible silhouette at ``cam`` against pre's image (bool (H, W)), or None."""
        if self.ensure() is None or self.layer is None:
            return None
        from r360gpu.render.rasterize import planes_to_numpy

        t = self.layer.image(cam)
        tp = planes_to_numpy(self.app.ctx, t.buffer, t.width, t.height)
        pp = planes_to_numpy(self.app.ctx, pre.buffer, pre.width, pre.height)
        plane = "depth" if pre.depth_plane == 4 else "median_depth"
        return projected_mask(tp["alpha"], tp[plane], pp[plane])

    def release(self) -> None:
        if self.layer is not None:
            self.layer.release()
