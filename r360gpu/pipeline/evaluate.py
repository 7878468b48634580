"""evaluate(): scenes in, the results document out."""
from __future__ import annotations

import contextvars
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..errors import InputError
from ..util import warning_log
from .cache import RunCache
from .options import EvaluateOptions, default_probes
from .picture_sink import PictureSink
from .results_doc import ResultsDocument
from .run import SceneRun, Timer
from .stages import gather


def evaluate(
    bundles,
    *,
    out=None,
    semantic_probes=None,
    structural_probes=None,
    options: EvaluateOptions | None = None,
    ctx=None,
    adapter: str | None = None,
    device=None,
    force: bool = False,
    progress: bool = True,
    log=print,
    executor=None,
    ray_address: str | None = None,
    kept=None,
) -> dict:
    """Score one or more scene bundles; returns the results document (a dict).

    bundles: bundle folders, :class:`~r360gpu.bundle.Bundle` objects, or
        scenes built from in-memory objects with
        :func:`~r360gpu.bundle.scene_from_objects` (Gaussians, or renders and
        depths already on the device).
    out: output folder: results.json, results.csv, tables.md/.tex, pictures,
        plots and report.html are written there, as ``r360gpu score`` does,
        and the per-view cache is kept there (None: nothing is written and
        nothing is cached).
    semantic_probes, structural_probes: lists of probes (default: the
        weight-free built-ins).  With several probes per axis the axes use the
        "most alarming" reading per view; each probe's own axes are kept.
    ctx / adapter / device: the GPU context, an adapter choice, or a caller's
        ``wgpu.GPUDevice``.
    force: recompute everything (the cache under ``out`` is cleared first).
    executor: None or "serial" (views scored here, overlapped), "ray"
        (uncached views scored as Ray tasks, :mod:`.distributed`; needs the
        ``r360gpu[ray]`` extra), or a :class:`~.distributed.RayExecutor`.
    ray_address: with executor="ray": "local" (default), "auto" or a cluster address.
    kept: renders made before (:class:`~r360gpu.render.kept.KeptRenders`, as
        ``r360gpu demo`` keeps the generator's reference renders), used where
        they are exactly what would be rendered; emptied when the run ends.
    """
    # One collector from the first file read: warnings of loading (a COLMAP model's distortion,
    # a BOM in prompt.txt) reach results.json as the pipeline's do.
    with warning_log.collecting():
        return _load_and_evaluate(bundles, out, semantic_probes, structural_probes, options, ctx, adapter, device,
                                  force, progress, log, executor, ray_address, kept)


def _load_and_evaluate(bundles, out, semantic_probes, structural_probes, options, ctx, adapter, device, force,
                       progress, log, executor, ray_address, kept) -> dict:
    from ..bundle import Bundle, load_bundle
    from ..gpu import get_context

    opts = options or EvaluateOptions()
    opts._check()  # before any work, also when a field was changed after the options were built
    host_threads()  # R360GPU_HOST_THREADS too
    if executor is not None or ray_address is not None:
        from .distributed import open_executor

        executor = open_executor(executor, ray_address=ray_address, adapter=adapter, device=device, log=log)
    ctx = ctx or get_context(adapter, device=device)
    # None: not given; each scene then takes its folder's probe outputs or the defaults (probes.registry.scene_probes)
    defaults = default_probes() if semantic_probes is None or structural_probes is None else None
    if isinstance(bundles, (str, Path, Bundle)):
        bundles = [bundles]
    sel = list(opts.views) if opts.views else None  # validated as `check --views` does
    loaded = [b if isinstance(b, Bundle) else load_bundle(b, views=sel) for b in bundles]
    loaded = [b.with_render_settings(antialiased=True if opts.antialiased else None) for b in loaded]
    if opts.compat:  # public folders: depth is read as the public scripts read it (aggregate.compat)
        from ..bundle.remove360_layout import without_depth

        loaded = [without_depth(b) for b in loaded]
    from ..bundle.names import check_bundle_names, name_problems

    for b in loaded:  # a Bundle built by hand or by scene_from_objects gets the checks of scene.toml
        check_bundle_names(b)
    names = [b.name for b in loaded]
    if len(set(names)) != len(names) or name_problems("scene", names):
        raise InputError(f"two bundles share a scene name (names are compared ignoring case): {names}")
    for line in missing_methods(loaded):
        log(f"note: {line}")
    out = Path(out) if out is not None else None
    cache = RunCache(out, force=force)
    sink = PictureSink(out, opts.pictures, embed_cache=cache.embed)
    with warning_log.collecting():
        try:
            return _evaluate(loaded, opts, ctx, (semantic_probes, structural_probes, defaults), cache, sink, out,
                             progress, log, executor, kept)
        finally:
            if kept is not None:
                kept.clear()


def _evaluate(loaded, opts, ctx, probes, cache, sink, out, progress, log, executor=None, kept=None) -> dict:
    from ..util.imports import ImportAhead

    # the cross-scene statistics (two scenes or more) use scipy.stats, first needed once every view is scored
    later = ImportAhead(*(["scipy.stats"] if len(loaded) >= 2 else []))
    timer = Timer()
    document = ResultsDocument(adapter=ctx.describe(), options={**opts.scoring_key(), "n_boot": opts.n_boot,
                                                                "n_perm": opts.n_perm, "seed": opts.seed})
    results = document.doc
    t_start = time.perf_counter()
    n_views_done = 0
    views_of: dict = {}

    from ..probes.registry import scene_probes

    def open_run(bundle) -> SceneRun:
        sem, stru, selection = scene_probes(bundle, probes[0], probes[1], compat=opts.compat, defaults=probes[2])
        with warning_log.where(scene=bundle.name):
            run = SceneRun(bundle, opts, ctx, sem, stru, cache=cache, timer=timer, kept=kept)
        run.probe_selection = selection
        return run

    def open_what_if(b, o) -> SceneRun:  # a scene seen elsewhere (orbit) or a method changed (pruned)
        sem, stru, _ = scene_probes(b, probes[0], probes[1], compat=o.compat, defaults=probes[2])
        return SceneRun(b, o, ctx, sem, stru, cache=cache, timer=timer)

    quiet = PictureSink(None, False)  # the what-ifs have no contact sheets
    scenes, plots = _ScenesAhead(loaded, open_run), _PlotsAhead(enabled=out is not None)
    try:
        for i, bundle in enumerate(loaded):
            run = scenes.take(i)
            _say_probes(run, log)
            _say_frames(run, log)
            with warning_log.where(scene=bundle.name):
                try:
                    scene_res = evaluate_scene(run, cache, sink, progress, executor, rendered=scenes.opener(i + 1))
                finally:
                    run.release()
            if opts.orbit:  # --orbit N: the scene from all around, under scenes.S.orbit (pipeline.orbit)
                from .orbit import score_orbit

                with warning_log.where(scene=bundle.name):
                    scene_res["orbit"] = score_orbit(run.bundle, opts, open_what_if,
                                                     lambda r: evaluate_scene(r, cache, sink, progress), ctx=ctx,
                                                     warn=warning_log.warn)
            if opts.residuals or opts.prune_residuals:  # the Gaussians behind the evidence (.residuals)
                from .residuals import scene_residuals, score_pruned

                with warning_log.where(scene=bundle.name):
                    scene_res["residuals"], values = scene_residuals(run.bundle, scene_res, out, ctx=ctx,
                                                                     xis=opts.xis, warn=warning_log.warn)
                    if opts.prune_residuals:  # the unranked what-if METHOD+pruned, under scenes.S.pruned
                        scene_res["pruned"] = score_pruned(run.bundle, values, opts, open_what_if,
                                                           lambda r: evaluate_scene(r, cache, quiet, progress), out)
            views_of[bundle.name] = {v: k for k, v in enumerate(run.views)}
            if opts.compat:
                from ..aggregate.compat import apply_compat

                apply_compat(scene_res, bundle, opts.compat, xis=opts.xis, ght=opts.ght)
            document.add_scene(bundle.name, scene_res, run.probes_desc, selection=run.probe_selection)
            n_views_done += len(run.views)
            plots.draw(bundle.name, scene_res)
        document.set_timing(timer.totals, time.perf_counter() - t_start, n_views_done,
                            executor.describe() if executor is not None else None)
        if executor is not None:
            executor.close()
        later.wait()
        document.aggregate(n_boot=opts.n_boot, n_perm=opts.n_perm, seed=opts.seed)
        document.set_warnings(in_run_order(warning_log.records(), [b.name for b in loaded], views_of),
                              warning_log.counts())
        if out is not None:
            from ..report.outputs import write_run_outputs

            write_run_outputs(results, out, embed_cache=cache.embed, plots=plots.drawn())
    finally:
        scenes.close()
        plots.close()
    return results


def _say_probes(run: SceneRun, log) -> None:
    """On the console: which probes a public folder's scene runs and why (its own outputs or not)."""
    if getattr(run.bundle, "layout", None) != "remove360":
        return
    for axis, sel in (getattr(run, "probe_selection", None) or {}).items():
        log(f"probes: {run.bundle.name} {axis}: {', '.join(sel['probes'])} ({sel['source']}) -- {sel['why']}")


def _say_frames(run: SceneRun, log) -> None:
    """On the console: the splat sources whose cameras are moved into another frame (r360gpu.io.frames)."""
    named = [("pre", run.pre), ("reference", run.reference), *run.methods.items()]
    for name, src in named:
        frame = getattr(src, "frame", None)
        if frame is not None:
            log(f"frame: {run.bundle.name} {name}: cameras moved by {frame.origin} (scale {frame.scale:.6g}; "
                f"depth reported in the cameras' units)")


class _ScenesAhead:
    """The scenes' runs, opened in order; the next one may be opened ahead of its turn.

    A scene's :func:`opener` is called (on the GPU thread) once the scene before it has
    rendered its last view: its sources are loaded and its probes fitted while the host
    threads finish the views before.
    """

    def __init__(self, loaded: list, open_run):
        self.loaded, self.open_run, self.opened = loaded, open_run, {}

    def take(self, i: int) -> SceneRun:
        run = self.opened.pop(i, None)
        if isinstance(run, Exception):  # opening it ahead failed: the error comes at its turn, as it
            raise run                   # would have, once the scene before is scored and cached
        return run if run is not None else self.open_run(self.loaded[i])

    def opener(self, i: int):
        def open_ahead() -> None:
            if i < len(self.loaded) and i not in self.opened:
                try:
                    self.opened[i] = self.open_run(self.loaded[i])
                except Exception as e:  # noqa: BLE001 (raised again by take)
                    self.opened[i] = e

        return open_ahead

    def close(self) -> None:
        """Release runs opened ahead and never taken (the run stopped before their turn)."""
        for run in self.opened.values():
            if not isinstance(run, Exception):
                run.release()
        self.opened.clear()


class _PlotsAhead:
    """Each finished scene's plots, drawn on a thread of their own while the next scene is scored."""

    def __init__(self, enabled: bool):
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="r360-plots") if enabled else None
        self.jobs: dict = {}

    def draw(self, scene: str, entry: dict) -> None:
        if self.pool is not None:
            from ..report.outputs import method_plots, scene_records

            self.jobs[scene] = self.pool.submit(method_plots, scene, scene_records(entry))

    def drawn(self) -> dict:
        """{scene: {method: PNG bytes}} (waits for the last scene's)."""
        return {scene: job.result() for scene, job in self.jobs.items()}

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)


def in_run_order(records: list[dict], scenes: list[str], views_of: dict) -> list[dict]:
    """The warning records by scene (in ``scenes`` order; run-wide ones first), then view (in
    ``views_of[scene]`` order; scene-wide ones first), else in the order they were raised.

    Threads raise warnings in the order they get to them, and a scene may be opened while
    the last views of the one before are still probed; this order is the same every run,
    serial or distributed.
    """
    scene_ix = {s: k for k, s in enumerate(scenes)}

    def key(rec: dict) -> tuple[int, int]:
        s, v = rec.get("scene"), rec.get("view")
        return scene_ix.get(s, -1), (-1 if v is None else views_of.get(s, {}).get(v, -1))

    return sorted(records, key=key)


def missing_methods(bundles) -> list[str]:
    """One line per scene that lacks some of the methods the other scenes have."""
    every = list(dict.fromkeys(m for b in bundles for m in b.methods))
    lines = []
    for b in bundles:
        gone = [m for m in every if m not in b.methods]
        if gone:
            lines.append(f"scene {b.name} has no method {', '.join(gone)}; the cross-scene tables use the "
                         f"methods every scene has")
    return lines


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
    import os

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
                   rendered=None) -> dict:
    """Every view of one scene (from the view cache where it has them); the scene's results entry.

    rendered: called (once, on this thread) when the last view to score here is rendered.
    """
    from ..aggregate.results import method_axes
    from ..aggregate.validity import scene_validity
    from ..metrics.record import ViewRecord

    bundle, opts = run.bundle, run.opts
    view_cache, cells_of, todo = _cached_views(run, cache, sink)
    if todo and run.fit_pending and run.fit():
        # the fit record no longer holds: the key changes, so look the views up again
        view_cache, cells_of, todo = _cached_views(run, cache, sink)
    for v in cells_of:
        warning_log.replay(next(iter(cells_of[v].values())).get("warnings"))
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
    for v, cells in score_views(run, todo, sink, view_cache, rendered=rendered):
        cells_of[v] = cells
        next(ticks, None)
    scored = [*bundle.methods, *run.controls.values()]
    records: dict = {m: [] for m in scored}
    boundaries: dict = {m: [] for m in scored}
    pictures: dict = {m: {} for m in scored}
    for v in run.views:
        for m, cell in cells_of[v].items():
            records[m].append(ViewRecord.from_dict(cell["record"]))
            boundaries[m].append(cell.get("boundary"))
            if cell.get("picture"):
                pictures[m][v] = cell["picture"]
    scene = {
        "prompt": bundle.prompt,
        "n_views": len(run.views),
        "views": run.views,
        "reference": bundle.reference is not None,
        "structural_mode": run.mode,
        "depth": run.depth_mode,
        "sources": run.describe_sources(),
        "methods": {},
    }
    if getattr(run, "frame_check", None):  # do pre's cameras see its splats (r360gpu.metrics.frame_check)
        scene["frame_check"] = run.frame_check
    if run.target_record is not None:  # [target]: which views' masks were given, which rendered
        scene["target"] = run.target_record
    if getattr(bundle, "expected", None):  # scene.toml [expected.METHOD]: known failures, checked by the report
        scene["expected"] = bundle.expected
    for m in bundle.methods:
        axes = method_axes(records[m], xis=opts.xis, boundary=boundaries[m] if opts.boundary else None)
        scene["methods"][m] = {"axes": axes, "views": [r.to_dict() for r in records[m]], "pictures": pictures[m]}
    if run.controls:
        scene["controls"] = {c: {"source": src, "axes": method_axes(records[src], xis=opts.xis),
                                 "views": [r.to_dict() for r in records[src]]}
                             for c, src in run.controls.items()}
    scene["validity"], scene["validity_notes"], scene["detectability"] = scene_validity(scene, xi=0.3)
    return scene


def _cached_views(run: SceneRun, cache: RunCache, sink: PictureSink):
    """(view cache, {view: cells} of the views it has, views to score)."""
    if run.fingerprint is None:  # renders held on the device: what they hold is not known, nothing is cached
        return None, {}, list(run.views)
    view_cache = cache.views(run.bundle.name, {
        "bundle": run.fingerprint, "options": run.opts.scoring_key(), "probes": run.probes_desc, "mode": run.mode,
        "depth": run.depth_mode, "lpips": run.lpips.describe() if run.lpips else None})
    cells_of, todo = {}, []
    for v in run.views:
        cells = view_cache.load_view(run.bundle.methods, v, pictures=sink.enabled) if view_cache else None
        if cells is not None and run.controls:  # the controls' cells (no pictures) must be there too
            ctl = view_cache.load_view(run.controls.values(), v, pictures=False)
            cells = None if ctl is None else {**cells, **ctl}
        if cells is None:
            todo.append(v)
        else:
            cells_of[v] = cells
    return view_cache, cells_of, todo


def score_views(run: SceneRun, views: list, sink: PictureSink, view_cache, rendered=None):
    """Score ``views``, yielding (view, cells) in order, with the stages overlapped:

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
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    from .stages import measure, on_host, picture_jobs, render_on_device, view_sources
    from .writer import BackgroundWriter

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
            # a view's warnings go with its first cell (once: counts add up on replay)
            next(iter(cells.values()))["warnings"] = warning_log.for_view(run.bundle.name, v)
            writer.submit(contextvars.copy_context().run, _finish_view, run, sink, view_cache, v, cells, jobs)
            run.done(v)
            yield v, cells
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


def _finish_view(run: SceneRun, sink: PictureSink, view_cache, view: str, cells: dict, jobs: list) -> None:
    """Writer thread: the view's pictures, then its cache cells."""
    import time

    t = time.perf_counter()
    if jobs:
        sink.view(jobs)
    if jobs:
        run.timer.add("pictures", t)
    if view_cache is not None:
        view_cache.store_view(view, cells, run.changed_inputs(view))


def _progress(views, desc, enabled):
    from ..util.progress import progress

    return progress(views, desc=desc, unit="view", enabled=enabled)
