"""The overlapped schedule of one scene's views: cached views first, the rest rendered, probed,
measured and written at once on their threads.

One thread (the caller's, which holds the GPU context) renders each view on the
device and measures it; :func:`host_threads` threads read the view's files and
run its probes ahead of it; :func:`writer_threads` threads write its pictures and
then its cache cells.  Views are measured and yielded in their order whatever
finishes first, so the results do not depend on the thread counts.
"""
from __future__ import annotations

import contextvars
import os
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor

from ..errors import InputError
from ..protocol import XI_DEFAULT
from ..schema import SceneEntry, ScoredView
from ..util import warning_log
from ..util.progress import progress
from .cache import RunCache
from .picture_sink import PictureSink
from .run import SceneRun
from .stages import gather, measure, on_host, picture_jobs, render_on_device, view_sources
from .writer import BackgroundWriter


#: Views whose host-side work (reading, probes) may run ahead of the view being measured, at least.
LOOKAHEAD = 2
#: Threads for the host-side work at most; the GPU thread and the writer thread come on top.
MAX_HOST_THREADS = 8


def host_threads() -> int:
    """Threads that read a view's files and run its probes, several views at once.

    One per CPU core beyond the GPU and writer threads, between 2 and
    :data:`MAX_HOST_THREADS`: the probes spend most of their time in OpenCV and
    numpy, which release the GIL, so a many-core machine runs that many views'
    probes at once (the built-in probes' Python parts still share one core's
    worth of GIL).  ``R360GPU_HOST_THREADS`` sets the count (at least 1), e.g.
    to compare counts in a benchmark.  Results do not depend on it: views are
    measured and written in their order whatever finishes first.
    """
    given = os.environ.get("R360GPU_HOST_THREADS", "").strip()
    if given:
        try:
            n = int(given)
        except ValueError:
            n = 0
        if n < 1:
            raise InputError(f"R360GPU_HOST_THREADS must be a whole number >= 1, got {given!r}")
        return n
    return max(2, min(MAX_HOST_THREADS, (os.cpu_count() or 2) - 2))


def evaluate_scene(run: SceneRun, cache: RunCache, sink: PictureSink, progress: bool, executor=None,
                   rendered=None, what_if: bool = False) -> SceneEntry:
    """Every view of one scene (from the view cache where it has them); the scene's results entry.

    rendered: called (once, on this thread) when the last view to score here is rendered.
    what_if: a scene scored beside the capture views (the orbit, the pruned methods): with the
    compat depth rule, but without the capture scene's compat values and notes.
    """
    bundle = run.bundle
    view_cache, cells_of, todo = _cached_views(run, cache, sink)
    if todo and run.fit_pending and run.fit():
        # the fit record no longer holds: the key changes, so look the views up again
        view_cache, cells_of, todo = _cached_views(run, cache, sink)
    for v in cells_of:
        warning_log.replay(cells_of[v].warnings)
        run.done(v)
    if executor is not None and todo:
        # The executor hook: the views the cache lacks are scored elsewhere (.distributed.RayExecutor),
        # which stores their cells (and pictures) in the cache as they arrive.
        cells_of.update(executor.score_scene(run, view_cache, sink, progress))
        todo = []
    done = f" ({len(cells_of)} cached)" if cells_of else ""
    # The progress iterator reports an item once the next one is asked for: primed with the
    # first view, advanced as each view is done.  score_views runs to its end (its writer
    # thread is then closed, every picture written) before the scene is assembled.
    ticks = iter(_progress(todo, f"scoring {bundle.name}{done}", progress))
    next(ticks, None)
    for v, scored in score_views(run, todo, sink, view_cache, rendered=rendered):
        cells_of[v] = scored
        next(ticks, None)
    return scene_entry(run, cells_of, what_if=what_if)


def scene_entry(run: SceneRun, cells_of: dict, *, what_if: bool = False) -> SceneEntry:
    """The scene's :class:`~r360gpu.schema.SceneEntry` from the cells of its views ({view: ScoredView}):
    the per-view records and the axes of every method and control, the controls' validity verdicts,
    and in a compat mode the public scripts' values (:mod:`r360gpu.aggregate.compat`).  The
    records (ViewRecord objects) become dicts here."""
    from ..aggregate.compat import scene_compat
    from ..aggregate.results import method_axes
    from ..aggregate.validity import scene_validity

    bundle, opts = run.bundle, run.opts
    scored = [*bundle.methods, *run.controls.values()]
    records: dict = {m: [] for m in scored}
    boundaries: dict = {m: [] for m in scored}
    pictures: dict = {m: {} for m in scored}
    for v in run.views:
        for m, cell in cells_of[v].cells.items():
            records[m].append(cell.record)
            boundaries[m].append(cell.boundary)
            if cell.picture:
                pictures[m][v] = cell.picture
    own = {m: {"axes": method_axes(records[m], xis=opts.xis, boundary=boundaries[m] if opts.boundary else None),
               "views": [r.to_dict() for r in records[m]]} for m in bundle.methods}
    controls = {c: {"source": src, "axes": method_axes(records[src], xis=opts.xis),
                    "views": [r.to_dict() for r in records[src]]}
                for c, src in run.controls.items()} if run.controls else None
    # The verdicts weigh r360gpu's own readings (its probes, on the controls as on the methods),
    # also in a compat mode, whose method axes are the public scripts'.
    validity, validity_notes, detectability = scene_validity({"methods": own, "controls": controls}, xi=XI_DEFAULT)
    compat = None if what_if else scene_compat(bundle, list(bundle.methods), opts.compat, xis=opts.xis,
                                               ght=opts.ght)
    methods = {m: {"axes": compat.axes(entry["axes"]) if compat else entry["axes"],
                   "views": [compat.view(d) for d in entry["views"]] if compat else entry["views"],
                   "pictures": pictures[m]} for m, entry in own.items()}
    return SceneEntry(**_scene_header(run), methods=methods, controls=controls, validity=validity,
                      validity_notes=validity_notes, detectability=detectability,
                      notes=compat.notes if compat is not None else None)


def _scene_header(run: SceneRun) -> dict:
    """The scene entry's description of the run (the :class:`~r360gpu.schema.SceneEntry` fields before
    its measures)."""
    bundle = run.bundle
    return {
        "prompt": bundle.prompt,
        "n_views": len(run.views),
        "views": run.views,
        "reference": bundle.reference is not None,
        "structural_mode": run.mode,
        "depth": run.depth_mode,
        "sources": run.describe_sources(),
        "frame_check": run.frame_check or None,  # do pre's cameras see its splats (r360gpu.metrics.frame_check)
        "target": run.target_record,  # [target]: which views' masks were given, which rendered
        # scene.toml [expected.METHOD]: known failures, checked by the report
        "expected": bundle.expected or None,
    }


def _cached_views(run: SceneRun, cache: RunCache, sink: PictureSink):
    """(view cache, {view: ScoredView} of the views it has, views to score)."""
    if run.fingerprint is None:  # renders held on the device: what they hold is not known, nothing is cached
        return None, {}, list(run.views)
    view_cache = cache.views(run.bundle.name, {
        "bundle": run.fingerprint, "options": run.opts.scoring_key(), "probes": run.probes_desc, "mode": run.mode,
        "depth": run.depth_mode, "lpips": run.lpips.describe() if run.lpips else None})
    cells_of, todo = {}, []
    for v in run.views:
        # the controls' cells (no pictures) must be there too
        scored = view_cache.load_scored(run.bundle.methods, run.controls.values(), v, pictures=sink.enabled) \
            if view_cache else None
        if scored is None:
            todo.append(v)
        else:
            cells_of[v] = scored
    return view_cache, cells_of, todo


def score_views(run: SceneRun, views: list, sink: PictureSink, view_cache, rendered=None):
    """Score ``views``, yielding (view, ScoredView) in order, with the stages overlapped:

    this (the GPU) thread renders on the device and measures; :func:`host_threads`
    threads read renders, masks and run the probes, one view ahead per thread
    (at least ``LOOKAHEAD``); :func:`writer_threads` writer threads write each
    view's pictures and then its cache cells (so a cached cell always has its
    picture).  Once the first view's
    size is known (when it is rendered, or when its files are read), fewer
    views are kept in flight when they would hold more than ``MEMORY_BUDGET``
    bytes (large images: 4K and up).  ``rendered`` is called once the last
    view is rendered.
    """
    if not views:
        return
    # files read by the host threads: a view's size is known once its first one is read
    host_sources = any(on_host(source) for _, _, source in view_sources(run))
    threads = host_threads()
    host = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="r360-host")
    writer = None
    lookahead = 0  # until the first view's size is known
    inflight: deque = deque()
    ok = False
    try:
        pending = iter(views)
        while True:
            while len(inflight) <= lookahead:
                v = next(pending, None)
                if v is None:
                    if rendered is not None:
                        rendered, call = None, rendered
                        call()
                    break
                with warning_log.where(view=v):
                    data = render_on_device(run, v)
                if writer is None and not host_sources:  # every image is here: its size is known now
                    lookahead, bound = _in_flight(_view_bytes(data), threads)
                    writer = BackgroundWriter(bound=bound, workers=writer_threads(threads))
                # contextvars do not follow work into a pool: the run's warning log and the
                # view's place in it go along explicitly
                inflight.append((v, host.submit(contextvars.copy_context().run, _gather, run, data)))
            if not inflight:
                break
            v, fut = inflight.popleft()
            data = fut.result()
            if writer is None:
                lookahead, bound = _in_flight(_view_bytes(data), threads)
                writer = BackgroundWriter(bound=bound, workers=writer_threads(threads))
            with warning_log.where(view=v):
                cells, geos = measure(run, data, sink)
                jobs = picture_jobs(run, data, geos, cells) if sink.enabled else []
            scored = ScoredView(cells, warning_log.for_view(run.bundle.name, v))
            writer.submit(contextvars.copy_context().run, _finish_view, run, sink, view_cache, v, scored, jobs)
            run.done(v)
            yield v, scored
        ok = True
    finally:
        for _, fut in inflight:
            fut.cancel()
        host.shutdown(wait=True, cancel_futures=True)
        if writer is not None:
            writer.close(wait_errors=ok)


#: Bytes of renders the overlapped schedule may hold beyond the view being measured.
MEMORY_BUDGET = 2 << 30


def _gather(run: SceneRun, data):
    with warning_log.where(view=data.view):
        return gather(run, data)


def _view_bytes(data) -> int:
    imgs = [*data.pres.values(), data.ref, *data.posts.values()]
    return sum(getattr(a, "nbytes", 0) for im in imgs if im is not None for a in (im.rgb, im.depth, im.alpha))


def _in_flight(view_bytes: int, threads: int = 1) -> tuple[int, int]:
    """(views read ahead, views waiting for the writers) within MEMORY_BUDGET (at least 0 and 1).

    Up to one view ahead per host thread (at least LOOKAHEAD), so every thread
    has a view to work on, and a view waiting for each writer."""
    ahead = max(LOOKAHEAD, threads)
    slots = MEMORY_BUDGET // max(1, view_bytes)
    lookahead = min(ahead, max(0, slots // 2))
    return lookahead, min(max(LOOKAHEAD + 1, writer_threads(threads) + 1), max(1, slots - lookahead))


def writer_threads(threads: int) -> int:
    """Writer threads beside ``threads`` host threads: a contact sheet costs about a third of a view's
    probes on one core, so one writer per two host threads (one on a 2-core machine)."""
    return max(1, threads // 2)


def _finish_view(run: SceneRun, sink: PictureSink, view_cache, view: str, scored: ScoredView, jobs: list) -> None:
    """Writer thread: the view's pictures, then its cache cells."""
    t = time.perf_counter()
    if jobs:
        sink.view(jobs)
    if jobs:
        run.timer.add("pictures", t)
    if view_cache is not None:
        view_cache.store_view(view, scored, run.changed_inputs(view))


def _progress(views, desc, enabled):
    return progress(views, desc=desc, unit="view", enabled=enabled)
