"""A bundle's ``[target]`` made concrete: the target over pre's Gaussians and a mask for every view.

Used by the scoring pipeline when a bundle declares ``[target]``
(:mod:`r360gpu.bundle.target`): views with a given mask keep it, every other
view gets the lifted target's mask rendered over pre
(:mod:`r360gpu.lift.masks`), and the run records which were which.
"""
from __future__ import annotations

from contextlib import closing
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..render.sources import frame_of
from .masks import target_masks
from .occluders import find_occluders
from .target import check_extent, lift_target, load_indices, target_from_box, target_from_indices

#: Fewer given masks than this: the lifted target is doubtful (one view cannot tell depth).
MIN_LIFT_VIEWS = 2


def _given_masks(bundle, warn=None) -> tuple[dict, dict]:
    """({view: (H, W) bool}, {view: its file}) of the views with a given mask, decoded and checked against the camera (an
    error names the mask's file); a mask whose every pixel is target is warned about, and refused when
    every given mask is."""
    from ..io import load_mask

    out, paths = {}, {}
    spec = bundle.target
    extra = spec.masks if isinstance(spec.masks, dict) else {}
    for v in bundle.cameras:
        m = extra.get(v, bundle.masks.get(v))
        if m is None:
            continue
        c = bundle.cameras[v]
        paths[v] = f"target mask of view {v!r}" if isinstance(m, np.ndarray) else str(m)
        out[v] = np.asarray(m) != 0 if isinstance(m, np.ndarray) else load_mask(m, shape=(c.height, c.width))
        if out[v].shape != (c.height, c.width):
            raise InputError(f"{paths[v]}: mask is {'x'.join(map(str, out[v].shape[::-1]))}, the camera of "
                             f"view {v!r} is {c.width}x{c.height}")
    full = [v for v in sorted(out) if out[v].all()]
    if full and len(full) == len(out):
        raise InputError(f"every given target mask is target at every pixel ({', '.join(paths[v] for v in full[:3])}"
                         f"{', ...' if len(full) > 3 else ''}): inverted masks? nothing would be left around "
                         f"the object", _where(bundle))
    for v in full:
        if warn is not None:
            warn(f"{paths[v]}: the target mask is target at every pixel (inverted?)")
    return out, paths


def _where(bundle) -> str:
    """The file that declared the bundle's target (its scene.toml; the folder or scene name otherwise)."""
    config = getattr(bundle, "config", None)
    return str(config if config is not None else getattr(bundle, "root", None) or f"scene {bundle.name!r}")


def lifted_target(bundle, gaussians, *, ctx=None, options=None, frame=None, warn=None):
    """(LiftedTarget, given masks {view: (H, W) bool}) for ``bundle.target`` over pre's ``gaussians``
    (in ``frame``, a `Frame`; None: the cameras').

    The one validation of a ``[target]`` (``r360gpu check`` runs it too, :func:`check_target`):
    the indices file (type, range), the box (some but not every Gaussian inside), the given masks
    (decoded, at their camera's size, not every pixel target), and the lift holding some but not
    every Gaussian; every error names the file.  Masks that cover an occluder in front of the
    object (`r360gpu.lift.occluders`) are warned about, naming them."""
    spec = bundle.target
    where = _where(bundle)
    given, paths = _given_masks(bundle, warn)
    if spec.indices is not None and spec.box is not None and warn is not None:
        warn(f"{where}: [target] gives both indices and box; the indices define the target and the box is "
             f"ignored (remove one)")
    if spec.indices is not None:
        rows = dict(rows=gaussians.file_rows, warn=warn)  # the user's indices are rows of pre's file
        if isinstance(spec.indices, np.ndarray):
            lifted = target_from_indices(gaussians.n_file, spec.indices, where="target indices", **rows)
        else:
            lifted = load_indices(spec.indices, gaussians.n_file, prop=spec.prop, **rows)
        return check_extent(lifted, str(spec.indices) if isinstance(spec.indices, Path) else where, warn), given
    if spec.box is not None:
        return (check_extent(target_from_box(gaussians.means, spec.box, where=where), f"{where}: [target].box", warn),
                given)
    views = [v for v in sorted(given) if given[v].any()]
    if not views:
        raise InputError(f"no given target mask shows the target (scene {bundle.name!r}); nothing to lift", where)
    if len(views) < MIN_LIFT_VIEWS and warn is not None:
        warn(f"target lifted from {len(views)} view's mask only ({views[0]}): depth is ambiguous; "
             f"give masks of at least {MIN_LIFT_VIEWS} views")
    cams = [bundle.cameras[v] for v in views]
    lifted = lift_target(gaussians, cams, [given[v] for v in views], ctx=ctx, options=options, frame=frame,
                         per_view=warn is not None and len(views) >= MIN_LIFT_VIEWS)
    check_extent(lifted, f"{where}: [target].masks", warn)
    if lifted.w_views is not None:
        occ = find_occluders(gaussians, cams, lifted, frame=frame)
        if occ.doubtful:
            warn(f"{where}: [target].masks: {occ.message(paths)}")
        unchanged = _against_reference(bundle, gaussians, {v: given[v] for v in views}, ctx=ctx, options=options,
                                       frame=frame)
        if unchanged is not None and unchanged.doubtful:
            warn(f"{where}: [target].masks: {unchanged.message(paths)}")
    return replace(lifted, w_views=None), given  # (V, 2, N) weights are not kept past the check


def _against_reference(bundle, gaussians, masks: dict, *, ctx=None, options=None, frame=None):
    """The given ``masks`` ({view: (H, W) bool}) against the bundle's reference
    (`r360gpu.lift.occluders.unchanged_masks`), pre and the reference rendered (or read) at their
    views; None without a reference with depth."""
    from dataclasses import asdict

    from ..render.sources import SceneSource, open_source
    from .occluders import unchanged_masks

    if getattr(bundle, "reference", None) is None:
        return None
    look = dict(ctx=ctx, background=bundle.options.background, depth=bundle.options.depth)
    ref = open_source(bundle.reference, **look)
    pre = SceneSource(gaussians, **look, render=None if options is None else asdict(options), frame=frame)
    try:
        refs = {v: ref.images(v, bundle.cameras[v]) for v in masks}
        if any(img.depth is None for img in refs.values()):
            return None
        return unchanged_masks(masks, {v: pre.images(v, bundle.cameras[v]) for v in masks}, refs)
    finally:
        pre.release()
        ref.release()


def _view_masks(bundle, gaussians, lifted, given: dict, *, ctx=None, options=None, frame=None):
    """(view, (H, W) bool target mask) for each selected view: the given masks, then the others
    rendered from ``lifted`` over pre's ``gaussians`` (lazily: a consumer may stop early)."""
    yield from ((v, given[v]) for v in bundle.views if v in given)
    todo = [v for v in bundle.views if v not in given]
    if todo:
        yield from zip(todo, target_masks(gaussians, lifted.target, [bundle.cameras[v] for v in todo], ctx=ctx,
                                          options=options, frame=frame))


def _require_shown(bundle, lifted, shown: bool) -> None:
    """InputError (naming the file that gave the target) unless some selected view shows it: a
    target whose Gaussians every view sees hidden or not at all leaves nothing to evaluate."""
    if shown or not bundle.views:
        return
    spec = bundle.target
    where = str(spec.indices) if isinstance(spec.indices, Path) else _where(bundle)
    raise InputError(f"the target ({lifted.source}, {int(lifted.target.sum())} of pre's {lifted.n} Gaussians) "
                     f"shows in none of the {len(bundle.views)} selected views: every view's target mask, given "
                     f"or rendered over pre, is empty (are these Gaussians hidden behind others, or outside "
                     f"every camera?)", where)


def check_target(bundle, *, ctx=None, warn=None):
    """The LiftedTarget of a valid bundle's ``[target]`` over its pre, validated as ``score`` does
    (:func:`lifted_target`, pre opened by :func:`~r360gpu.render.sources.open_source`, and some
    selected view showing the target, as `resolve_lifted` requires): what ``r360gpu check`` runs so
    that its OK means ``score`` accepts the target."""
    from ..render.sources import open_source

    pre = open_source(bundle.pre, ctx=ctx, background=bundle.options.background)
    try:
        if getattr(pre, "gaussians", None) is None:
            raise InputError(f"scene {bundle.name!r}: [target] needs pre as a splat scene", _where(bundle))
        ctx = pre.renderer.ctx if ctx is None else ctx
        options, frame = getattr(pre, "render_options", None), frame_of(pre)
        lifted, given = lifted_target(bundle, pre.gaussians, ctx=ctx, options=options, frame=frame, warn=warn)
        # as score needs: some selected view shows the target (stops at the first that does: one
        # render in the usual case)
        with closing(_view_masks(bundle, pre.gaussians, lifted, given, ctx=ctx, options=options,
                                 frame=frame)) as masks:
            _require_shown(bundle, lifted, any(m.any() for _, m in masks))
        return lifted
    finally:
        release = getattr(pre, "release", None)
        if release is not None:
            release()


def resolve_target(bundle, pre, *, ctx=None, warn=None):
    """(bundle with a mask for every view, record) for a bundle with ``[target]``.

    pre: the opened pre source (a :class:`~r360gpu.render.sources.SceneSource`).  record:
    {"source", "gaussians", "of", "given", "rendered", "lifted_from"} for results.json ("gaussians" of
    pre's "of" Gaussians are the target).
    """
    return resolve_lifted(bundle, pre, ctx=ctx, warn=warn)[:2]


def resolve_lifted(bundle, pre, *, ctx=None, warn=None):
    """(bundle, record, LiftedTarget): `resolve_target` and the target it lifted."""
    if getattr(pre, "gaussians", None) is None:
        raise InputError(f"scene {bundle.name!r}: [target] needs pre as a splat scene")
    options = getattr(pre, "render_options", None)
    frame = frame_of(pre)
    lifted, given = lifted_target(bundle, pre.gaussians, ctx=ctx, options=options, frame=frame, warn=warn)
    masks = dict(_view_masks(bundle, pre.gaussians, lifted, given, ctx=ctx, options=options, frame=frame))
    _require_shown(bundle, lifted, any(m.any() for m in masks.values()))
    todo = [v for v in bundle.views if v not in given]
    record = {"source": lifted.source, "gaussians": int(lifted.target.sum()), "of": int(pre.gaussians.n),
              "given": sorted(v for v in bundle.views if v in given), "rendered": todo,
              "lifted_from": list(lifted.views)}
    return replace(bundle, masks=masks), record, lifted


def scene_target(bundle, gaussians, *, ctx=None, options=None, frame=None, warn=None, capture=None):
    """The LiftedTarget of any bundle with cameras: its ``[target]``, else its views' masks lifted
    (views with a camera and a non-empty mask) to ``gaussians`` in ``frame`` (None: the cameras'),
    with the whole weights over ``capture`` (`lift_target`; not for a ``[target]``)."""
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
    return check_extent(lift_target(gaussians, cams, masks, ctx=ctx, options=options, frame=frame, capture=capture),
                        f"{_where(bundle)}: masks", warn)
