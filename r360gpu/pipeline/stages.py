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
from typing import TYPE_CHECKING

from ..errors import InputError
from ..metrics import depth_checks
from ..probes.base import ProbeView
from ..schema import ScoredView, ViewCell
from ..util import warning_log
from .picture_sink import PictureJob

if TYPE_CHECKING:  # the render package is imported once a scene's sources are opened
    from ..render.sources import Source


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
    inputs: dict = field(default_factory=dict)  # {path: stamp} of the probes' per-view files, before reading


def on_host(source: Source) -> bool:
    """True for sources that only read files (safe to run off the GPU thread)."""
    return source.kind == "renders"


def view_sources(run):
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
        data.ref = run.render_reference(data.view)
    else:
        data.posts[key] = run.images(source, data.view)


def render_on_device(run, view: str) -> ViewData:
    """Render the sources that live on the GPU (call from the GPU thread)."""
    t = time.perf_counter()
    data = ViewData(view)
    for slot, key, source in view_sources(run):
        if not on_host(source):
            _render(run, data, slot, key, source)
    run.timer.add("render", t)
    return data


def _check_size(view, img, what, mask):
    if img is not None and img.rgb.shape[:2] != mask.shape:
        raise InputError(f"view {view}: {what} rendering is {img.rgb.shape[1]}x{img.rgb.shape[0]} "
                         f"but the target mask is {mask.shape[1]}x{mask.shape[0]} (W x H)")


def _ask(data: ViewData, probe, images, rendering, method=None, *prompt):
    """``probe``'s reading of one rendering of the view; the stamps of the files it reads for it
    (precomputed masks) go into ``data.inputs`` first."""
    data.inputs.update(probe.input_stamps(data.view, rendering, method))
    return probe.predict([ProbeView(name=data.view, image=images.rgb, rendering=rendering, method=method)],
                         *prompt)[0]


def gather(run, data: ViewData) -> ViewData:
    """Read the host-side renders and the mask, check sizes, and run every probe."""
    view = data.view
    t = time.perf_counter()
    for slot, key, source in view_sources(run):
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
    data.sem_pre = {n: {p.name: _ask(data, p, img, "pre", None, prompt) for p in run.sem}
                    for n, img in data.pres.items()}
    if run.mode == "reference":
        data.str_ref = {p.name: _ask(data, p, data.ref, "ref") for p in run.stru}
    else:
        data.str_pre = {n: {p.name: _ask(data, p, img, "pre") for p in run.stru} for n, img in data.pres.items()}
    for m, post in data.posts.items():
        data.sem_post[m] = {p.name: _ask(data, p, post, "post", m, prompt) for p in run.sem}
        data.str_post[m] = {p.name: _ask(data, p, post, "post", m) for p in run.stru}
    gather_controls(run, data)
    run.timer.add("probe", t)
    return data


def gather_controls(run, data: ViewData) -> None:
    """The controls' renders and probe readings, keyed by source name ("pre", "reference").

    The renders are the ones the methods are compared with.  The probes read
    them as the renderings they are ("pre", "ref"), so precomputed probes use
    the masks given for those renderings, and a reading already taken is reused.
    """
    prompt = run.bundle.prompt
    for src in run.controls.values():
        rendering, img = ("pre", data.pres["pre"]) if src == "pre" else ("ref", data.ref)
        data.posts[src] = img
        if src == "pre":
            data.sem_post[src] = data.sem_pre["pre"]
        else:
            data.sem_post[src] = {p.name: _ask(data, p, img, rendering, None, prompt) for p in run.sem}
        if src == "pre" and run.mode == "reference_free":
            data.str_post[src] = data.str_pre["pre"]
        elif src == "reference" and run.mode == "reference":
            data.str_post[src] = data.str_ref
        else:
            data.str_post[src] = {p.name: _ask(data, p, img, rendering) for p in run.stru}


def structural_pairs(run, data: ViewData, method: str) -> dict:
    """{probe: (masks_a, masks_b)}: (post, reference) in reference mode, (pre, post) without one."""
    str_post = data.str_post[method]
    if run.mode == "reference":
        return {p.name: (str_post[p.name], data.str_ref[p.name]) for p in run.stru}
    pre = data.str_pre[run.pre_of[method]]
    return {p.name: (pre[p.name], str_post[p.name]) for p in run.stru}


def measure_methods(run, data: ViewData, methods: list, *, boundary_sweep: bool = True) -> dict:
    """The three axes, fidelity and the boundary sweep (unless ``boundary_sweep`` is False) of
    ``methods`` (methods or controls) at one view: {method: MethodMeasures}.

    The methods that share a pre source are measured in one batch
    (:func:`r360gpu.metrics.measure.measure_view_methods`: I_ref, D_pre and
    the perturbed targets are prepared once), with the same values as one
    method at a time.
    """
    from ..metrics.measure import MeasureJob, MethodOutputs, measure_view_methods

    groups: dict = {}
    for m in methods:
        groups.setdefault(run.pre_of[m], []).append(m)
    settings = run.measure_settings(boundary_sweep=boundary_sweep)
    out = {}
    for pre_name, group in groups.items():
        pre, ref = data.pres[pre_name], data.ref
        first = data.str_ref if run.mode == "reference" else data.str_pre[pre_name]
        outs = {m: MethodOutputs(rgb=data.posts[m].rgb, depth=data.posts[m].depth, semantic=data.sem_post[m],
                                 structural=data.str_post[m]) for m in group}
        measured = measure_view_methods(MeasureJob(
            view=data.view, scene=run.bundle.name, target=data.mask, methods=outs,
            semantic_pre={p.name: data.sem_pre[pre_name][p.name] for p in run.sem},
            structural_first={p.name: first[p.name] for p in run.stru},
            pre_depth=pre.depth, ref_rgb=None if ref is None else ref.rgb), settings)
        for m, res in measured.items():
            if res.geometric is not None:
                _check_depth(run, data, m, res.record, pre, data.posts[m])
            out[m] = res
    return out


def _check_depth(run, data: ViewData, method: str, record, pre, post) -> None:
    """Warn about (and note in the record) a post depth with no valid pixel or in another unit than pre's."""
    from ..render.sources import host_depth

    is_method = method in run.bundle.methods  # else a control: the "pre" or "reference" source
    source = run.bundle.sources().get(method)  # a method, or the control's "pre" / "reference"
    d_pre, d_post = host_depth(pre.depth, run.ctx), host_depth(post.depth, run.ctx)  # the run's own device
    depth_checks.annotate(record, depth_checks.check_view(
        run.bundle.name, method, data.view, d_pre, d_post, data.mask, source=getattr(source, "path", None),
        label=None if is_method else f"[{method}]",
        pre_source=lambda: _depth_file(run.bundle.pre_of(method) if is_method else run.bundle.pre, data.view)))


def _depth_file(spec, view: str):
    """The file a source's depth of ``view`` comes from (its depth image for renders, else the source's
    path), named in a warning about that depth."""
    if getattr(spec, "kind", None) == "renders":
        try:
            return spec.reader().depth_path(view)
        except InputError:
            pass
    return getattr(spec, "path", None)


def measure(run, data: ViewData, sink) -> tuple[dict, dict]:
    """Every method's and control's :class:`~r360gpu.schema.ViewCell` of the view ({source: cell}),
    and the methods' GeometricViews (for the pictures).

    A method's cell has its boundary table and the path the sink will write its picture to (None
    without pictures); a control's has neither.  Every cell gets the stamps of the precomputed
    probe files read for the view (``data.inputs``).
    """
    t = time.perf_counter()
    cells, geos = {}, {}
    for m, res in measure_methods(run, data, list(run.methods)).items():
        geos[m] = res.geometric
        cells[m] = ViewCell(res.record, res.boundary, sink.path_for(run.bundle.name, m, data.view), data.inputs)
    controls = list(run.controls.values())
    for src, res in measure_methods(run, data, controls, boundary_sweep=False).items():  # no sweep, no picture
        cells[src] = ViewCell(res.record, None, None, data.inputs)
    run.timer.add("measure", t)
    return cells, geos


def picture_jobs(run, data: ViewData, geos: dict, cells: dict | None = None) -> list:
    """The view's picture jobs (:class:`~.picture_sink.PictureJob`), one per method.

    Reads device depth back here (the GPU thread), so the sink works on host arrays only: each
    image's once, however many methods share it (a pre source is every method's).
    """
    from ..render.sources import host_depth

    read: dict = {}

    def depth_of(img):
        if id(img.depth) not in read:
            read[id(img.depth)] = host_depth(img.depth, run.ctx)
        return read[id(img.depth)]

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
            d_pre, d_post = depth_of(pre), depth_of(post)
        cell = (cells or {}).get(m)
        jobs.append(PictureJob(scene=run.bundle.name, method=m, view=data.view, pre_rgb=pre.rgb, post_rgb=post.rgb,
                               ref_rgb=None if ref is None else ref.rgb, pre_depth=d_pre, post_depth=d_post,
                               mask=data.mask, geo=geo, compat=run.opts.compat, semantic=semantic,
                               structural=structural, record=None if cell is None else cell.record))
    return jobs


def score_view(run, view: str, sink) -> ScoredView:
    """One view's :class:`~r360gpu.schema.ScoredView`, stage after stage in this thread (pictures
    written here too), with the warnings raised for it."""
    data = gather(run, render_on_device(run, view))
    cells, geos = measure(run, data, sink)
    if sink.enabled:
        t = time.perf_counter()
        for job in picture_jobs(run, data, geos, cells):
            sink.method_view(job)
        run.timer.add("pictures", t)
    return ScoredView(cells, warning_log.for_view(run.bundle.name, view))
