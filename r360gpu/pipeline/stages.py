"""The per-view stages: render -> probe -> measure, then the picture.

:func:`score_view` runs them for one view of a :class:`~.run.SceneRun` and
returns one JSON-ready cell per method: ``{"record", "boundary", "picture"}``.
Each stage is a small function of the run and the view's data, so a view's
work can be split across threads or processes.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from ..errors import InputError


@dataclass
class Controls:
    """What every method of a view is compared with: the pre renders (by pre
    name), the reference render, and the probes' readings of them."""

    pres: dict
    ref: object
    sem_pre: dict          # {pre name: {probe name: SemanticPrediction}}
    str_pre: dict          # {pre name: {probe name: MaskSet}} (reference-free mode)
    str_ref: dict | None   # {probe name: MaskSet} (reference mode)


def _check_size(view, img, what, mask):
    if img is not None and img.rgb.shape[:2] != mask.shape:
        raise InputError(f"view {view}: the {what} rendering is {img.rgb.shape[1]}x{img.rgb.shape[0]} "
                         f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")


def _probe_views(view, images, rendering, method=None):
    from ..probes.base import ProbeView

    return [ProbeView(name=view, image=images.rgb, rendering=rendering, method=method)]


def render_controls(run, view: str, mask):
    """Render every pre source the methods use, and the reference."""
    t = time.perf_counter()
    pres = {name: run.render_pre(name, view) for name in dict.fromkeys(run.pre_of.values())}
    ref = run.reference.images(view, run.camera(view)) if run.reference is not None else None
    run.timer.add("render", t)
    for name, img in pres.items():
        _check_size(view, img, name, mask)
    _check_size(view, ref, "reference", mask)
    return pres, ref


def probe_controls(run, view: str, pres: dict, ref) -> Controls:
    t = time.perf_counter()
    prompt = run.bundle.prompt
    sem_pre = {n: {p.name: p.predict(_probe_views(view, img, "pre"), prompt)[0] for p in run.sem}
               for n, img in pres.items()}
    str_pre, str_ref = {}, None
    if run.mode == "reference":
        str_ref = {p.name: p.predict(_probe_views(view, ref, "ref"))[0] for p in run.stru}
    else:
        str_pre = {n: {p.name: p.predict(_probe_views(view, img, "pre"))[0] for p in run.stru}
                   for n, img in pres.items()}
    run.timer.add("probe", t)
    return Controls(pres, ref, sem_pre, str_pre, str_ref)


def render_method(run, method: str, view: str, mask):
    t = time.perf_counter()
    post = run.methods[method].images(view, run.camera(view))
    run.timer.add("render", t)
    if post.rgb.shape[:2] != mask.shape:
        raise InputError(f"view {view}: method {method}'s rendering is {post.rgb.shape[1]}x{post.rgb.shape[0]} "
                         f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")
    return post


def probe_method(run, method: str, view: str, post):
    """The probes' readings of one method's rendering: ({semantic}, {structural}) by probe name."""
    t = time.perf_counter()
    sem_post = {p.name: p.predict(_probe_views(view, post, "post", method), run.bundle.prompt)[0] for p in run.sem}
    str_post = {p.name: p.predict(_probe_views(view, post, "post", method))[0] for p in run.stru}
    run.timer.add("probe", t)
    return sem_post, str_post


def structural_pairs(run, controls: Controls, pre_name: str, str_post: dict) -> dict:
    """{probe: (masks_a, masks_b)}: (post, reference) in reference mode, (pre, post) without one."""
    if run.mode == "reference":
        return {p.name: (str_post[p.name], controls.str_ref[p.name]) for p in run.stru}
    return {p.name: (controls.str_pre[pre_name][p.name], str_post[p.name]) for p in run.stru}


def measure_method(run, method: str, view: str, mask, controls: Controls, post, sem_post, pairs, *,
                   boundary_sweep: bool = True):
    """The three axes, fidelity and the boundary sweep (unless ``boundary_sweep`` is False) of one method at one view.

    Returns (ViewRecord, boundary table or None, GeometricView or None).
    """
    from ..metrics.fidelity import fidelity_view
    from ..metrics.geometric import acc_depth_view
    from ..metrics.record import ViewRecord
    from ..metrics.semantic import semantic_view
    from ..metrics.sensitivity import NOT_GIVEN, BoundaryInput, boundary_sensitivity
    from ..metrics.structural import structural_view

    t = time.perf_counter()
    opts, ctx = run.opts, run.ctx
    pre_name = run.pre_of[method]
    pre, ref, sem_pre = controls.pres[pre_name], controls.ref, controls.sem_pre[pre_name]
    sem_views = [semantic_view(sem_pre[p.name], sem_post[p.name], mask, view=view, ctx=ctx) for p in run.sem]
    str_views = [structural_view(a, b, mask, mode=run.mode, view=view, ctx=ctx) for a, b in pairs.values()]
    geo = None
    if pre.depth is not None and post.depth is not None:
        geo = acc_depth_view(pre.depth, post.depth, mask, compat=opts.compat, ght_params=opts.ght, ctx=ctx)
    fid = fidelity_view(post.rgb, ref.rgb, run.lpips) if ref is not None else None
    record = ViewRecord.build(view, run.bundle.name, method,
                              probes=run.probes_desc["semantic"] + run.probes_desc["structural"],
                              semantic=sem_views, structural=str_views, geometric=geo, fidelity=fid)
    if geo is not None:
        from ..metrics import depth_checks

        is_method = method in run.bundle.methods  # else a control: the "pre" or "reference" source
        source = run.bundle.methods[method] if is_method else getattr(run.bundle, method, None)
        from ..render.sources import host_depth

        d_pre, d_post = host_depth(pre.depth, ctx), host_depth(post.depth, ctx)  # read on the run's own device
        depth_checks.annotate(record, depth_checks.check_view(
            run.bundle.name, method, view, d_pre, d_post, mask, source=getattr(source, "path", None),
            label=None if is_method else f"[{method}]"))
    boundary = None
    if boundary_sweep and opts.boundary and run.sem and run.stru:
        p0s, p0t = run.sem[0].name, run.stru[0].name
        a, b = pairs[p0t]
        table = boundary_sensitivity(
            [BoundaryInput(mask, pred_pre=sem_pre[p0s], pred_post=sem_post[p0s], masks_a=a, masks_b=b,
                           geometric=geo if geo is not None else NOT_GIVEN, view=view)],
            geometric=geo is not None, structural_mode=run.mode, xis=opts.xis, compat=opts.compat,
            ght_params=opts.ght, ctx=ctx,
        )
        boundary = {row: table.row(row) for row in table.rows}
    run.timer.add("measure", t)
    return record, boundary, geo


def picture_method(run, sink, method: str, view: str, mask, controls: Controls, post, sem_post, pairs, geo,
                   record=None):
    """Hand one method-view to the picture sink; returns the picture's path or None."""
    if not sink.enabled:
        return None
    t = time.perf_counter()
    pre, ref = controls.pres[run.pre_of[method]], controls.ref
    first = run.sem[0].name if run.sem else None
    structural = []
    if run.stru:
        a, b = pairs[run.stru[0].name]
        other = ("I_ref", ref) if run.mode == "reference" else ("I_pre", pre)
        names = (("I_post", post), other) if run.mode == "reference" else (other, ("I_post", post))
        structural = [(f"{run.stru[0].name} on {n}", img.rgb, ms) for (n, img), ms in zip(names, (a, b))]
    semantic = (controls.sem_pre[run.pre_of[method]][first], sem_post[first]) if first else None
    rel = sink.method_view(run.bundle.name, method, view, pre=pre, post=post, ref=ref, mask=mask, geo=geo,
                           compat=run.opts.compat, semantic=semantic, structural=structural,
                           record=None if record is None else record.to_dict())
    run.timer.add("pictures", t)
    return rel


def score_view(run, view: str, sink) -> dict:
    """Every method's cell of one view: {method: {"record", "boundary", "picture"}}."""
    mask = run.mask(view)
    controls = probe_controls(run, view, *render_controls(run, view, mask))
    cells = {}
    for m in run.methods:
        post = render_method(run, m, view, mask)
        sem_post, str_post = probe_method(run, m, view, post)
        pairs = structural_pairs(run, controls, run.pre_of[m], str_post)
        record, boundary, geo = measure_method(run, m, view, mask, controls, post, sem_post, pairs)
        picture = picture_method(run, sink, m, view, mask, controls, post, sem_post, pairs, geo, record)
        cells[m] = {"record": record.to_dict(), "boundary": boundary, "picture": picture}
    cells.update(score_controls(run, view, mask, controls))
    return cells


def score_controls(run, view: str, mask, controls: Controls) -> dict:
    """The controls' cells of one view, keyed by source name ("pre", "reference").

    The renders are the ones the methods were compared with.  The probes read
    them as the renderings they are ("pre", "ref"), so precomputed probes use
    the masks given for those renderings, and a reading already taken is
    reused.  No boundary sweep, no picture.
    """
    cells = {}
    for src in run.controls.values():
        rendering, img = ("pre", controls.pres["pre"]) if src == "pre" else ("ref", controls.ref)
        t = time.perf_counter()
        if src == "pre":
            sem_post = controls.sem_pre["pre"]
        else:
            sem_post = {p.name: p.predict(_probe_views(view, img, rendering), run.bundle.prompt)[0] for p in run.sem}
        if src == "pre" and run.mode == "reference_free":
            str_post = controls.str_pre["pre"]
        elif src == "reference" and run.mode == "reference":
            str_post = controls.str_ref
        else:
            str_post = {p.name: p.predict(_probe_views(view, img, rendering))[0] for p in run.stru}
        run.timer.add("probe", t)
        pairs = structural_pairs(run, controls, "pre", str_post)
        record, _, _ = measure_method(run, src, view, mask, controls, img, sem_post, pairs, boundary_sweep=False)
        cells[src] = {"record": record.to_dict(), "boundary": None, "picture": None}
    return cells
