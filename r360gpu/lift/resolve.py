"""A bundle's ``[target]`` made concrete: the target over pre's Gaussians and a mask for every view.

Used by the scoring pipeline when a bundle declares ``[target]``
(:mod:`r360gpu.bundle.target`): views with a given mask keep it, every other
view gets the lifted target's mask rendered over pre
(:mod:`r360gpu.lift.masks`), and the run records which were which.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..render.sources import frame_of
from .masks import TargetMaskRenderer
from .target import lift_target, load_indices, target_from_box, target_from_indices

#: Fewer given masks than this: the lifted target is doubtful (one view cannot tell depth).
MIN_LIFT_VIEWS = 2


def _given_masks(bundle) -> dict:
    from ..io import load_mask

    out = {}
    spec = bundle.target
    extra = spec.masks if isinstance(spec.masks, dict) else {}
    for v in bundle.cameras:
        m = extra.get(v, bundle.masks.get(v))
        if m is None:
            continue
        c = bundle.cameras[v]
        out[v] = np.asarray(m) != 0 if isinstance(m, np.ndarray) else load_mask(m, shape=(c.height, c.width))
        if out[v].shape != (c.height, c.width):
            raise InputError(f"target mask of view {v!r} is {out[v].shape[1]}x{out[v].shape[0]}, "
                             f"its camera {c.width}x{c.height}")
    return out


def lifted_target(bundle, gaussians, *, ctx=None, options=None, frame=None, warn=None):
    """(LiftedTarget, given masks {view: (H, W) bool}) for ``bundle.target`` over pre's ``gaussians``
    (in ``frame``, :class:`~r360gpu.io.frames.Frame`; None: the cameras')."""
    spec = bundle.target
    given = _given_masks(bundle)
    if spec.indices is not None:
        if isinstance(spec.indices, np.ndarray):
            return target_from_indices(gaussians.n, spec.indices, where="target indices"), given
        return load_indices(spec.indices, gaussians.n, prop=spec.prop), given
    if spec.box is not None:
        return target_from_box(gaussians.means, spec.box), given
    views = [v for v in sorted(given) if given[v].any()]
    if not views:
        raise InputError(f"scene {bundle.name!r}: no given target mask shows the target; nothing to lift")
    if len(views) < MIN_LIFT_VIEWS and warn is not None:
        warn(f"target lifted from {len(views)} view's mask only ({views[0]}): depth is ambiguous; "
             f"give masks of at least {MIN_LIFT_VIEWS} views")
    lifted = lift_target(gaussians, [bundle.cameras[v] for v in views], [given[v] for v in views], ctx=ctx,
                         options=options, frame=frame)
    if not lifted.target.any():
        raise InputError(f"scene {bundle.name!r}: the target masks lift to no Gaussian of pre")
    return lifted, given


def resolve_target(bundle, pre, *, ctx=None, warn=None):
    """(bundle with a mask for every view, record) for a bundle with ``[target]``.

    pre: the opened pre source (a :class:`~r360gpu.render.sources.SceneSource`).  record:
    {"source", "gaussians", "given", "rendered", "lifted_from"} for results.json.
    """
    if getattr(pre, "gaussians", None) is None:
        raise InputError(f"scene {bundle.name!r}: [target] needs pre as a splat scene")
    options = getattr(pre, "render_options", None)
    frame = frame_of(pre)
    lifted, given = lifted_target(bundle, pre.gaussians, ctx=ctx, options=options, frame=frame, warn=warn)
    masks = {v: given[v] for v in bundle.views if v in given}
    todo = [v for v in bundle.views if v not in given]
    if todo:
        r = TargetMaskRenderer(pre.gaussians, lifted.target, ctx=ctx, options=options, frame=frame)
        try:
            for v in todo:
                masks[v] = r.mask(bundle.cameras[v])
        finally:
            r.release()
    record = {"source": lifted.source, "gaussians": int(lifted.target.sum()),
              "given": sorted(v for v in bundle.views if v in given), "rendered": todo,
              "lifted_from": list(lifted.views)}
    return replace(bundle, masks=masks), record


def scene_target(bundle, gaussians, *, ctx=None, options=None, frame=None, warn=None):
    """The LiftedTarget of any bundle with cameras: its ``[target]``, else its views' masks lifted
    (views with a camera and a non-empty mask) to ``gaussians`` in ``frame`` (None: the cameras')."""
    if getattr(bundle, "target", None) is not None:
        return lifted_target(bundle, gaussians, ctx=ctx, options=options, frame=frame, warn=warn)[0]
    from ..io import load_mask

    cams, masks = [], []
    for v in bundle.views:
        c = (bundle.cameras or {}).get(v)
        m = bundle.masks.get(v)
        if c is None or m is None:
            continue
        m = np.asarray(m) != 0 if isinstance(m, np.ndarray) else load_mask(m, shape=(c.height, c.width))
        if m.any():
            cams.append(c)
            masks.append(m)
    if not cams:
        raise InputError(f"scene {bundle.name!r}: no view with a camera shows the target; cannot lift it")
    lifted = lift_target(gaussians, cams, masks, ctx=ctx, options=options, frame=frame)
    if not lifted.target.any():
        raise InputError(f"scene {bundle.name!r}: the target masks lift to no Gaussian of pre")
    return lifted
