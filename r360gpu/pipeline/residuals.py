"""Residuals on Gaussians (``score --residuals``, ``--prune-residuals Q``): per splat method, the
Gaussians behind the evidence, and the method scored again without them.

Writes ``residuals/SCENE/METHOD.ply`` (the method's Gaussians with a
``residual`` property, :mod:`r360gpu.lift.residuals`) and records in the
scene's results entry, per method, the file, the flagged views, the indices
of the :data:`TOP` highest residuals above 0 and whether the residual was gated by
the surface pre has behind the target.  Methods given as renderings have no
Gaussians: they are listed with a note.

``--prune-residuals Q`` removes each splat method's top residual Gaussians
(Q of them, or the fraction Q of its Gaussians) and scores what is left as
``METHOD+pruned`` at the capture views: a what-if that goes under
``scenes.S.pruned``, beside the method and never among ``scenes.S.methods``,
so no rank, aggregate or statistic sees it.
"""
from __future__ import annotations

from dataclasses import replace
from numbers import Integral, Real
from pathlib import Path

import numpy as np

from ..aggregate.results import per_view_axes
from ..bundle.names import DERIVED_SUFFIXES
from ..errors import InputError
from ..io import Gaussians, load_mask
from ..io.inria_ply import save_ply
from ..lift.residuals import depth_behind, flagged_views, residuals, surface_depth, top_residuals, write_residual_ply
from ..lift.resolve import scene_target
from ..protocol import XI_DEFAULT
from .orbit import _gaussians, _is_scene

#: Indices of the highest residuals recorded per method.
TOP = 100
#: The what-if entry of method M is named M + PRUNED (a name no method may take: bundle.names).
PRUNED = DERIVED_SUFFIXES[0]
#: The what-if of a method none of whose Gaussians has a residual (no view flags evidence).
NOTHING_TO_PRUNE = "not scored: no Gaussian has a residual (no view flags evidence)"


def check_prune(q) -> None:
    """InputError unless ``q`` is None, a count >= 1 or a fraction in (0, 1) (``--prune-residuals``)."""
    if q is None:
        return
    ok = (not isinstance(q, bool) and isinstance(q, Real) and
          ((isinstance(q, Integral) and q >= 1) or (not isinstance(q, Integral) and 0.0 < q < 1.0)))
    if not ok:
        raise InputError(f"prune_residuals (--prune-residuals) must be a count of Gaussians >= 1 or a "
                         f"fraction in (0, 1), got {q!r}")


def asked_count(q, n: int) -> int:
    """Gaussians ``--prune-residuals q`` asks to remove from a method of ``n``: ``q`` itself (a count)
    or round(q n), at least 1 (a fraction)."""
    return int(q) if isinstance(q, Integral) else max(1, int(round(float(q) * n)))


def prune_count(q, n: int) -> int:
    """Gaussians removed from a method of ``n``: `asked_count`, at most n (and never more than
    have a residual, `pruned_bundle`)."""
    return max(1, min(int(n), asked_count(q, n)))


def why_fewer(asked: int, n: int, n_residual: int) -> str | None:
    """Why a what-if removes fewer Gaussians than asked (None when it removes them all): a Gaussian
    with residual 0 carries no evidence (it is never blended inside the target of a flagged view in
    front of the surface behind it), so it is not pruned; nor can more than the method has be."""
    if min(asked, n_residual, n) == asked:
        return None
    if n_residual < min(asked, n):
        return (f"only {n_residual} Gaussians have a residual above 0 "
                f"(the rest add nothing inside the target of a flagged view)")
    return f"the method has only {n} Gaussians"


def _masks(bundle, cams) -> list:
    out = []
    for v, c in zip(bundle.views, cams):
        mk = bundle.masks[v]
        out.append(np.asarray(mk) != 0 if isinstance(mk, np.ndarray) else load_mask(mk, shape=(c.height, c.width)))
    return out


def _behind(bundle, cams, ctx, warn):
    """(per-view depth of the surface behind the target, or None, and how the residual was gated):
    the reference's when it is a splat scene (the capture after the removal shows exactly what the
    object hid), else pre's without the lifted target."""
    if bundle.reference is not None and _is_scene(bundle.reference):
        g, options, frame = _gaussians(bundle.reference)
        return (surface_depth(g, cams, ctx=ctx, options=options, frame=frame),
                "in front of the reference's surface")
    if not _is_scene(bundle.pre):
        return None, "none: pre is renderings only (M's share alone)"
    g, options, frame = _gaussians(bundle.pre)
    try:
        lifted = scene_target(bundle, g, ctx=ctx, options=options, frame=frame, warn=warn)
    except InputError as e:
        if warn is not None:
            warn(f"residuals: {e.problem}; residuals are M's share alone")
        return None, f"none: {e.problem}"
    return (depth_behind(g, lifted.target, cams, ctx=ctx, options=options, frame=frame),
            "in front of pre's surface behind the target")


def scene_residuals(bundle, methods: dict, out, *, ctx=None, xis=(XI_DEFAULT,), warn=None) -> tuple[dict, dict]:
    """({method: {"file", "flagged_views", "top", "max", "gate"} or {"note"}}, {method: (N,) residual})
    for ``bundle`` scored as ``methods`` (the scene entry's: {method: {"views": [view record dicts]}});
    the PLYs are written under ``out`` (None: not written)."""
    entry: dict = {}
    values: dict = {}
    cams = [bundle.cameras[v] for v in bundle.views] if bundle.cameras else []
    splat = {m: s for m, s in bundle.methods.items() if cams and _is_scene(s)}
    for m in bundle.methods:
        if m not in splat:
            entry[m] = {"note": "no residuals (renderings only)"}
    if not splat:
        return entry, values
    masks = _masks(bundle, cams)
    behind, gate = _behind(bundle, cams, ctx, warn)
    for m, spec in splat.items():
        flagged = flagged_views(per_view_axes(methods[m]["views"], xis=xis))
        g, options, frame = _gaussians(spec)
        r = residuals(g, cams, masks, flagged, behind=behind, ctx=ctx, options=options, frame=frame)
        values[m] = r
        # rows of the method's file as written (the loader may have dropped invalid ones)
        entry[m] = {"flagged_views": flagged, "top": g.rows[top_residuals(r, TOP)].tolist(),
                    "max": float(r.max()) if len(r) else 0.0, "gate": gate}
        if out is not None:
            write_residual_ply(Path(out) / "residuals" / bundle.name / f"{m}.ply", g, r,
                               source=getattr(spec, "path", None))
            entry[m]["file"] = str(Path("residuals") / bundle.name / f"{m}.ply")
    return dict(sorted(entry.items(), key=lambda kv: list(bundle.methods).index(kv[0]))), values


def pruned_bundle(bundle, values: dict, q, out):
    """(bundle whose methods are ``METHOD+pruned``: each splat method of ``values`` without its top
    residual Gaussians, {name: {"method", "removed", "of", "asked"[, "fewer"]}}: "fewer" says why
    fewer than asked were removed).  The pruned scenes are written as
    ``residuals/SCENE/METHOD+pruned.ply`` under ``out`` (kept in memory when ``out`` is None)."""
    methods, info = {}, {}
    for m, r in values.items():
        spec = bundle.methods[m]
        g, _, _ = _gaussians(spec)
        # only Gaussians with some residual are residual Gaussians: none when no view flags evidence
        n_residual = int(np.count_nonzero(np.asarray(r) > 0))
        asked = asked_count(q, g.n)
        k = min(prune_count(q, g.n), n_residual)
        if k == 0:
            info[m + PRUNED] = {"method": m, "removed": 0, "of": int(g.n), "note": NOTHING_TO_PRUNE}
            continue
        keep = np.ones(g.n, bool)
        keep[top_residuals(r, k)] = False
        pruned = g.subset(keep)
        name = m + PRUNED
        if isinstance(spec, Gaussians) or out is None:
            methods[name] = pruned
        else:  # the method's own render settings and frame go with the pruned file
            path = Path(out) / "residuals" / bundle.name / f"{name}.ply"
            path.parent.mkdir(parents=True, exist_ok=True)
            save_ply(path, pruned)
            methods[name] = replace(spec, path=path)
        info[name] = {"method": m, "removed": int(k), "of": int(g.n), "asked": asked}
        fewer = why_fewer(asked, int(g.n), n_residual)
        if fewer is not None:
            info[name]["fewer"] = fewer
        if out is not None and not isinstance(spec, Gaussians):
            info[name]["file"] = str(Path("residuals") / bundle.name / f"{name}.ply")
    pres = {m + PRUNED: s for m, s in bundle.method_pres.items() if m in values}
    return replace(bundle, methods=methods, method_pres=pres, target=None, expected={}), info


def score_pruned(bundle, values: dict, opts, open_run, evaluate_scene, out) -> dict:
    """The ``scenes.S.pruned`` entry: {METHOD+pruned: {"method", "removed", "of", "q", "axes", "views"}},
    each method re-scored without its top residuals at the capture views (never ranked); a method
    with no residual Gaussian gets {"method", "removed": 0, "of", "q", "note"} and is not scored.

    open_run(bundle, opts) opens a SceneRun; evaluate_scene(run) scores it (the pipeline's own).
    """
    if not values:
        return {}
    b, info = pruned_bundle(bundle, values, opts.prune_residuals, out)
    out_entry = {name: {**i, "q": opts.prune_residuals} for name, i in info.items()}
    if b.methods:
        run = open_run(b, replace(opts, orbit=0, residuals=False, prune_residuals=None, controls=False))
        try:
            res = evaluate_scene(run)
        finally:
            run.release()
        for name in b.methods:
            out_entry[name].update(axes=res.methods[name]["axes"], views=res.methods[name]["views"])
    return out_entry
