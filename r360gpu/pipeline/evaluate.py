"""evaluate(): scenes in, the results document out."""
from __future__ import annotations

import time
from pathlib import Path

from .. import __version__
from ..errors import InputError
from .cache import RunCache
from .options import EvaluateOptions, default_probes
from .pictures import PictureSink
from .run import SceneRun, Timer, WarningLog


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
) -> dict:
    """Score one or more scene bundles; returns the results document (a dict).

    bundles: bundle folders, :class:`~r360gpu.bundle.Bundle` objects, or
        scenes built from in-memory objects with
        :func:`~r360gpu.bundle.scene_from_objects` (Gaussians, or renders and
        depths already on the device).
    out: output folder for results.json, tables, pictures and report.html
        (None: nothing is written and nothing is cached).
    semantic_probes, structural_probes: lists of probes (default: the
        weight-free built-ins).  With several probes per axis the axes use the
        "most alarming" reading per view; each probe's own axes are kept.
    ctx / adapter / device: the GPU context, an adapter choice, or a caller's
        ``wgpu.GPUDevice``.
    force: recompute everything (the cache under ``out`` is cleared first).
    """
    from ..aggregate.pooling import aggregate_results
    from ..bundle import Bundle, load_bundle
    from ..gpu import get_context

    opts = options or EvaluateOptions()
    ctx = ctx or get_context(adapter, device=device)
    if semantic_probes is None or structural_probes is None:
        d_sem, d_str = default_probes()
        semantic_probes = d_sem if semantic_probes is None else semantic_probes
        structural_probes = d_str if structural_probes is None else structural_probes
    if isinstance(bundles, (str, Path, Bundle)):
        bundles = [bundles]
    loaded = [b if isinstance(b, Bundle) else load_bundle(b) for b in bundles]
    names = [b.name for b in loaded]
    if len(set(names)) != len(names):
        raise InputError(f"two bundles share a scene name: {names}")
    methods = list(loaded[0].methods)
    out = Path(out) if out is not None else None
    cache = RunCache(out, force=force)
    sink = PictureSink(out, opts.pictures)
    timer = Timer()
    warnings = WarningLog(log=log)
    results = {
        "schema": "r360gpu.results/1",
        "r360gpu_version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "adapter": ctx.describe(),
        "options": {**opts.scoring_key(), "n_boot": opts.n_boot, "n_perm": opts.n_perm, "seed": opts.seed},
        "probes": {},
        "scenes": {},
    }
    t_start = time.perf_counter()
    n_views_done = 0
    for bundle in loaded:
        if list(bundle.methods) != methods:
            log(f"note: scene {bundle.name} has methods {list(bundle.methods)}; "
                f"cross-scene tables need the same methods everywhere ({methods})")
        run = SceneRun(bundle, opts, ctx, semantic_probes, structural_probes, cache=cache, timer=timer,
                       warnings=warnings)
        try:
            results["scenes"][bundle.name] = evaluate_scene(run, cache, sink, progress)
        finally:
            run.release()
        results["probes"] = run.probes_desc
        n_views_done += len(run.views)
    results["timing"] = {"stages_s": {k: round(v, 3) for k, v in timer.totals.items()},
                         "total_s": round(time.perf_counter() - t_start, 3),
                         "views": n_views_done}
    if warnings.items:
        results["warnings"] = warnings.items
    aggregate_results(results, n_boot=opts.n_boot, n_perm=opts.n_perm, seed=opts.seed)
    return results


#: Views whose host-side work (reading, probes) may run ahead of the view being measured.
LOOKAHEAD = 2
#: Threads for the host-side work; the GPU thread and the writer thread come on top.
HOST_THREADS = 2


def evaluate_scene(run: SceneRun, cache: RunCache, sink: PictureSink, progress: bool) -> dict:
    """Every view of one scene (from the view cache where it has them); the scene's results entry."""
    from ..aggregate.results import method_axes
    from ..metrics.record import ViewRecord

    bundle, opts = run.bundle, run.opts
    view_cache, cells_of, todo = _cached_views(run, cache, sink)
    if todo and run.fit_pending and run.fit():
        # the fit record no longer holds: the key changes, so look the views up again
        view_cache, cells_of, todo = _cached_views(run, cache, sink)
    for v in cells_of:
        run.done(v)
    bar = _progress(len(run.views), len(run.views) - len(todo), bundle.name, progress)
    try:
        for v, cells in score_views(run, todo, sink, view_cache):
            cells_of[v] = cells
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    records: dict = {m: [] for m in bundle.methods}
    boundaries: dict = {m: [] for m in bundle.methods}
    pictures: dict = {m: {} for m in bundle.methods}
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
    for m in bundle.methods:
        axes = method_axes(records[m], xis=opts.xis, boundary=boundaries[m] if opts.boundary else None)
        scene["methods"][m] = {"axes": axes, "views": [r.to_dict() for r in records[m]], "pictures": pictures[m]}
    return scene


def _cached_views(run: SceneRun, cache: RunCache, sink: PictureSink):
    """(view cache, {view: cells} of the views it has, views to score)."""
    view_cache = cache.views(run.bundle.name, {
        "bundle": run.fingerprint, "options": run.opts.scoring_key(), "probes": run.probes_desc, "mode": run.mode,
        "depth": run.depth_mode, "lpips": run.lpips.describe() if run.lpips else None})
    cells_of, todo = {}, []
    for v in run.views:
        cells = view_cache.load_view(run.bundle.methods, v, pictures=sink.enabled) if view_cache else None
        if cells is None:
            todo.append(v)
        else:
            cells_of[v] = cells
    return view_cache, cells_of, todo


def score_views(run: SceneRun, views: list, sink: PictureSink, view_cache):
    """Score ``views``, yielding (view, cells) in order, with the stages overlapped:

    this (the GPU) thread renders on the device and measures; ``HOST_THREADS``
    threads read renders, masks and run the probes up to ``LOOKAHEAD`` views
    ahead; one writer thread writes the pictures and then the view's cache
    cells (so a cached cell always has its picture).  Once the first view's
    size is known, fewer views are kept in flight when they would hold more
    than ``MEMORY_BUDGET`` bytes (large images: 4K and up).
    """
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    from .stages import gather, measure, picture_jobs, render_on_device
    from .writer import BackgroundWriter

    if not views:
        return
    host = ThreadPoolExecutor(max_workers=HOST_THREADS, thread_name_prefix="r360-host")
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
                    break
                inflight.append((v, host.submit(gather, run, render_on_device(run, v))))
            if not inflight:
                break
            v, fut = inflight.popleft()
            data = fut.result()
            if writer is None:
                lookahead, bound = _in_flight(_view_bytes(data))
                writer = BackgroundWriter(bound=bound)
            cells, geos = measure(run, data, sink)
            jobs = picture_jobs(run, data, geos) if sink.enabled else []
            writer.submit(_finish_view, run, sink, view_cache, v, cells, jobs)
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


def _view_bytes(data) -> int:
    imgs = [*data.pres.values(), data.ref, *data.posts.values()]
    return sum(getattr(a, "nbytes", 0) for im in imgs if im is not None for a in (im.rgb, im.depth, im.alpha))


def _in_flight(view_bytes: int) -> tuple[int, int]:
    """(views read ahead, views waiting for the writer) within MEMORY_BUDGET (at least 0 and 1)."""
    slots = MEMORY_BUDGET // max(1, view_bytes)
    lookahead = min(LOOKAHEAD, max(0, slots // 2))
    return lookahead, min(LOOKAHEAD + 1, max(1, slots - lookahead))


def _finish_view(run: SceneRun, sink: PictureSink, view_cache, view: str, cells: dict, jobs: list) -> None:
    """Writer thread: the view's pictures, then its cache cells."""
    import time

    t = time.perf_counter()
    if jobs:
        sink.view(jobs)
    if jobs:
        run.timer.add("pictures", t)
    if view_cache is not None:
        for m, cell in cells.items():
            view_cache.store(m, view, cell)


def _progress(total: int, done: int, name: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=done, desc=f"scoring {name}", unit="view", dynamic_ncols=True, leave=True)
