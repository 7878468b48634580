"""The target object in 3D for the viewer: the pipeline's lifted target (:mod:`r360gpu.lift`).

The viewer uses the same target as scoring: a bundle's ``[target]``
(indices, box or masks) when it has one, else the evaluation views' target
masks lifted to pre's Gaussians by alpha compositing (at most
:data:`MAX_LIFT_VIEWS` views, evenly spaced).  The target's centre (median of
its Gaussians' centres) and radius (90th-percentile distance) drive "focus
on the target"; its mask at a viewpoint that is not an evaluation view is
the lifted target rendered over pre (:class:`r360gpu.lift.TargetMaskRenderer`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: At most this many evaluation views' masks are lifted (evenly spaced), to bound the start-up time.
MAX_LIFT_VIEWS = 24


@dataclass(frozen=True)
class Target:
    """The target: ``indices`` (int64) of pre's Gaussians, ``mask`` (N,) bool, ``centre`` (3,), ``radius``."""

    indices: np.ndarray
    mask: np.ndarray
    centre: np.ndarray
    radius: float


def lift_views(n: int) -> list[int]:
    """Indices of the at most MAX_LIFT_VIEWS views (evenly spaced) out of ``n`` whose masks are lifted."""
    if n <= 0:
        return []
    return [int(i) for i in np.unique(np.linspace(0, n - 1, min(MAX_LIFT_VIEWS, n)).round().astype(int))]


def estimate_target(gaussians, cameras: list, masks: list, *, ctx=None, options=None,
                    frame=None) -> Target | None:
    """The target lifted from ``masks`` ((H, W) bool, one per camera) over ``gaussians`` (pre, in
    ``frame``; None: the cameras'); None when no mask shows the target or nothing lifts."""
    from r360gpu.lift import lift_target

    if len(cameras) != len(masks):
        raise ValueError(f"{len(cameras)} cameras but {len(masks)} masks")
    pairs = [(c, m) for c, m in zip(cameras, masks) if np.asarray(m).any()]
    if not pairs:
        return None
    pairs = [pairs[i] for i in lift_views(len(pairs))]
    lifted = lift_target(gaussians, [c for c, _ in pairs], [m for _, m in pairs], ctx=ctx, options=options,
                         frame=frame)
    return _target(lifted, gaussians.means, frame)


def _target(lifted, means, frame=None) -> Target | None:
    """The Target of ``lifted`` over pre's ``means`` (in ``frame``), placed in the cameras' world,
    where the viewer's camera moves."""
    if not lifted.target.any():
        return None
    from r360gpu.io.frames import points_in_cameras

    centre, radius = lifted.extent(points_in_cameras(frame, means))
    return Target(lifted.indices, lifted.target, centre, radius)


class SceneTarget:
    """The app's target: made once on first use (pre splat + cameras + masks or [target]), then used
    to focus the camera and to give a target mask away from the evaluation views."""

    def __init__(self, app):
        self.app = app
        self.target: Target | None = None
        self.masks = None  # a TargetMaskRenderer over pre
        self._done = False

    def ensure(self) -> Target | None:
        """Lift the 3D target once, None when impossible."""
        from r360gpu.lift import TargetMaskRenderer
        from r360gpu.render.sources import frame_of

        from .layers import SplatLayer

        if self._done:
            return self.target
        self._done = True
        app = self.app
        pre = app.layers.get("pre")
        if not isinstance(pre, SplatLayer) or not app.cameras:
            return None
        source = pre.load()  # its render options and frame, as scoring renders it
        options, frame = getattr(source, "render_options", None), frame_of(source)
        if getattr(app.bundle, "target", None) is not None:
            from r360gpu.lift.resolve import lifted_target

            lifted, _ = lifted_target(app.bundle, pre.gaussians, ctx=app.ctx, options=options, frame=frame)
            self.target = _target(lifted, pre.gaussians.means, frame)
        else:
            pairs = [(v, c) for v, c in zip(app.views, app.view_cameras) if c is not None and v in app.bundle.masks]
            cams = [c for _, c in pairs]
            masks = [app.pictures.mask_of(v, c.width, c.height) for v, c in pairs]
            self.target = estimate_target(pre.gaussians, cams, masks, ctx=app.ctx, options=options, frame=frame)
        if self.target is not None:
            self.masks = TargetMaskRenderer(pre.gaussians, self.target.mask, ctx=app.ctx, options=options,
                                            frame=frame)
        return self.target

    def focus(self) -> None:
        """Point the camera at the target (at the pivot when there is no estimate)."""
        app = self.app
        target = self.ensure()
        if target is not None:
            app.camera.focus(target.centre, target.radius)
        else:
            app.camera.focus(app.camera.pivot, app.scale_length * 0.5)
            app.notify("no target (needs a splat pre scene, cameras and masks or [target]): focused on the pivot")

    def projected_mask(self, cam, pre=None) -> np.ndarray | None:
        """The target's mask at ``cam`` (bool (H, W)), rendered over pre; None without a target."""
        if self.ensure() is None or self.masks is None:
            return None
        return self.masks.mask(cam)

    def release(self) -> None:
        if self.masks is not None:
            self.masks.release()
