"""The per-view stages: render -> probe -> measure, then the pictures.

A view's work is split by where it may run:

* :func:`render_on_device` -- sources the GPU renders (splat scenes, renders
  already on the device): the thread that owns the GPU context;
* :func:`gather` -- everything host-side: renders made elsewhere (file
  reading and decoding), the target mask, and the probes; any thread;
* :func:`measure` -- the three axes, fidelity and the boundary sweep of
  every method, and the axes of the controls (GPU kernels): the GPU thread again;
* :func:`picture_jobs` -- the contact sheets, handed to the picture sink.

:func:`score_view` runs them one after the other for one view; the scene
loop in :mod:`.evaluate` overlaps them across views.  Every stage is a
function of the :class:`~.run.SceneRun` and the view's data, so a chunk of
views can as well be scored in another process that opens the same run.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..errors import InputError


@dataclass
class ViewData:
    """The renders and probe readings of one view.

    pres: {pre name: ViewImages}; ref: ViewImages or None; posts: {method: ViewImages};
    sem_pre: {pre name: {probe: SemanticPrediction}}; str_pre: {pre name: {probe: MaskSet}}
    (reference-free mode); str_ref: {probe: MaskSet} (reference mode);
    sem_post / str_post: {method: {probe: ...}}.
    """

    view: str
    pres: dict = field(default_factory=dict)
    ref: object = None
    posts: dict = field(default_factory=dict)
    mask: object = None
    sem_pre: dict = field(default_factory=dict)
    str_pre: dict = field(default_factory=dict)
    str_ref: dict | None = None
    sem_post: dict = field(default_factory=dict)
    str_post: dict = field(default_factory=dict)


def on_host(source) -> bool:
    """True for sources that only read files (safe to run off the GPU thread)."""
    return getattr(source, "kind", None) == "renders"


def _sources(run):
    """(slot, key, source) of every source a view needs: pre sources, the reference, the methods."""
    out = [("pre", name, run.pres[name]) for name in dict.fromkeys(run.pre_of.values())]
    if run.reference is not None:
        out.append(("ref", None, run.reference))
    out += [("post", m, s) for m, s in run.methods.items()]
    return out


def _render(run, data: ViewData, slot, key, source) -> None:
    if slot == "pre":
        data.pres[key] = run.render_pre(key, data.view)
    elif slot == "ref":
        data.ref = source.images(data.view, run.camera(data.view))
    else:
        data.posts[key] = source.images(data.view, run.camera(data.view))


def render_on_device(run, view: str) -> ViewData:
    """Render the sources that live on the GPU (call from the GPU thread)."""
    t = time.perf_counter()
    data = ViewData(view)
    for slot, key, source in _sources(run):
        if not on_host(source):
            _render(run, data, slot, key, source)
    run.timer.add("render", t)
    return data


def _check_size(view, img, what, mask):
    if img is not None and img.rgb.shape[:2] != mask.shape:
        raise InputError(f"view {view}: {what} rendering is {img.rgb.shape[1]}x{img.rgb.shape[0]} "
                         f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")


def _probe_views(view, images, rendering, method=None):
    from ..probes.base import ProbeView

    return [ProbeView(name=view, image=images.rgb, rendering=rendering, method=method)]


def gather(run, data: ViewData) -> ViewData:
    """Read the host-side renders and the mask, check sizes, and run every probe."""
    view = data.view
    t = time.perf_counter()
    for slot, key, source in _sources(run):
        if on_host(source):
            _render(run, data, slot, key, source)
    data.mask = mask = run.mask(view)
    t = run.timer.add("read", t)
    for name, img in data.pres.items():
        _check_size(view, img, f"the {name}", mask)
    _check_size(view, data.ref, "the reference", mask)
    for m, img in data.posts.items():
        _check_size(view, img, f"method {m}'s", mask)
    prompt = run.bundle.prompt
    data.sem_pre = {n: {p.name: p.predict(_probe_views(view, img, "pre"), prompt)[0] for p in run.sem}
                    for n, img in data.pres.items()}
    if run.mode == "reference":
        data.str_ref = {p.name: p.predict(_probe_views(view, data.ref, "ref"))[0] for p in run.stru}
    else:
        data.str_pre = {n: {p.name: p.predict(_probe_views(view, img, "pre"))[0] for p in run.stru}
                        for n, img in data.pres.items()}
    for m, post in data.posts.items():
        data.sem_post[m] = {p.name: p.predict(_probe_views(view, post, "post", m), prompt)[0] for p in run.sem}
        data.str_post[m] = {p.name: p.predict(_probe_views(view, post, "post", m))[0] for p in run.stru}
    gather_controls(run, data)
    run.timer.add("probe", t)
    return data


def gather_controls(run, data: ViewData) -> None:
    """The controls' renders and probe readings, keyed by source name ("pre", "reference").

    The renders are the ones the methods are compared with.  The probes read
    them as the renderings they are ("pre", "ref"), so precomputed probes use
    the masks given for those renderings, and a reading already taken is reused.
    """
    view, prompt = data.view, run.bundle.prompt
    for src in run.controls.values():
        rendering, img = ("pre", data.pres["pre"]) if src == "pre" else ("ref", data.ref)
        data.posts[src] = img
        if src == "pre":
            data.sem_post[src] = data.sem_pre["pre"]
        else:
            data.sem_post[src] = {p.name: p.predict(_probe_views(view, img, rendering), prompt)[0] for p in run.sem}
        if src == "pre" and run.mode == "reference_free":
            data.str_post[src] = data.str_pre["pre"]
        elif src == "reference" and run.mode == "reference":
            data.str_post[src] = data.str_ref
        else:
            data.str_post[src] = {p.name: p.predict(_probe_views(view, img, rendering))[0] for p in run.stru}


def structural_pairs(run, data: ViewData, method: str) -> dict:
    """{probe: (masks_a, masks_b)}: (post, reference) in reference mode, (pre, post) without one."""
    str_post = data.str_post[method]
    if run.mode == "reference":
        return {p.name: (str_post[p.name], data.str_ref[p.name]) for p in run.stru}
    pre = data.str_pre[run.pre_of[method]]
    return {p.name: (pre[p.name], str_post[p.name]) for p in run.stru}


def measure_method(run, data: ViewData, method: str, *, boundary_sweep: bool = True):
    """The three axes, fidelity and the boundary sweep (unless ``boundary_sweep`` is False) of one
    method (or control) at one view.

    Returns (ViewRecord, boundary table or None, GeometricView or None).
    """
    from ..metrics.fidelity import fidelity_view
    from ..metrics.geometric import acc_depth_view
    from ..metrics.record import ViewRecord
    from ..metrics.semantic import semantic_view
    from ..metrics.sensitivity import NOT_GIVEN, BoundaryInput, boundary_sensitivity
    from ..metrics.structural import structural_view

    opts, ctx, view, mask = run.opts, run.ctx, data.view, data.mask
    pre_name = run.pre_of[method]
    pre, post, ref = data.pres[pre_name], data.posts[method], data.ref
    sem_pre, sem_post = data.sem_pre[pre_name], data.sem_post[method]
    pairs = structural_pairs(run, data, method)
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
        _check_depth(run, data, method, record, pre, post)
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
    return record, boundary, geo


def _check_depth(run, data: ViewData, method: str, record, pre, post) -> None:
    """Warn about (and note in the record) a post depth with no valid pixel or in another unit than pre's."""
    from ..metrics import depth_checks
    from ..render.sources import host_depth

    is_method = method in run.bundle.methods  # else a control: the "pre" or "reference" source
    source = run.bundle.methods[method] if is_method else getattr(run.bundle, method, None)
    d_pre, d_post = host_depth(pre.depth, run.ctx), host_depth(post.depth, run.ctx)  # the run's own device
    depth_checks.annotate(record, depth_checks.check_view(
        run.bundle.name, method, data.view, d_pre, d_post, data.mask, source=getattr(source, "path", None),
        label=None if is_method else f"[{method}]"))


def measure(run, data: ViewData, sink) -> tuple[dict, dict]:
    """Every method's cell of the view, and its GeometricView (for the pictures).

    cells: {method: {"record", "boundary", "picture"}}; the picture is the
    path the sink will write (None without pictures).
    """
    t = time.perf_counter()
    cells, geos = {}, {}
    for m in run.methods:
        record, boundary, geos[m] = measure_method(run, data, m)
        cells[m] = {"record": record.to_dict(), "boundary": boundary,
                    "picture": sink.path_for(run.bundle.name, m, data.view)}
    for src in run.controls.values():  # no boundary sweep, no picture
        record, _, _ = measure_method(run, data, src, boundary_sweep=False)
        cells[src] = {"record": record.to_dict(), "boundary": None, "picture": None}
    run.timer.add("measure", t)
    return cells, geos


def picture_jobs(run, data: ViewData, geos: dict, cells: dict | None = None) -> list:
    """Keyword arguments of :meth:`~.pictures.PictureSink.method_view`, one per method.

    Reads device depth back here (the GPU thread), so the sink works on host arrays only.
    """
    from ..render.sources import host_depth

    jobs = []
    first = run.sem[0].name if run.sem else None
    for m in run.methods:
        pre, post, ref, geo = data.pres[run.pre_of[m]], data.posts[m], data.ref, geos[m]
        structural = []
        if run.stru:
            a, b = structural_pairs(run, data, m)[run.stru[0].name]
            other = ("I_ref", ref) if run.mode == "reference" else ("I_pre", pre)
            names = (("I_post", post), other) if run.mode == "reference" else (other, ("I_post", post))
            structural = [(f"{run.stru[0].name} on {n}", img.rgb, ms) for (n, img), ms in zip(names, (a, b))]
        semantic = (data.sem_pre[run.pre_of[m]][first], data.sem_post[m][first]) if first else None
        d_pre = d_post = None
        if geo is not None:
            d_pre, d_post = host_depth(pre.depth, run.ctx), host_depth(post.depth, run.ctx)
        jobs.append(dict(scene=run.bundle.name, method=m, view=data.view, pre_rgb=pre.rgb, post_rgb=post.rgb,
                         ref_rgb=None if ref is None else ref.rgb, pre_depth=d_pre, post_depth=d_post,
                         mask=data.mask, geo=geo, compat=run.opts.compat, semantic=semantic,
                         structural=structural, record=(cells or {}).get(m, {}).get("record")))
    return jobs


def score_view(run, view: str, sink) -> dict:
    """Every method's cell of one view, stage after stage in this thread (pictures written here too)."""
    data = gather(run, render_on_device(run, view))
    cells, geos = measure(run, data, sink)
    if sink.enabled:
        t = time.perf_counter()
        for job in picture_jobs(run, data, geos, cells):
            sink.method_view(**job)
        run.timer.add("pictures", t)
    return cells
