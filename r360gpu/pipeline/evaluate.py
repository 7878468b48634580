"""evaluate(): scenes in, the results document out."""
from __future__ import annotations

import time
from pathlib import Path

from .. import __version__
from ..errors import InputError
from .cache import RunCache, fingerprint
from .options import EvaluateOptions, default_probes
from .pictures import PictureSink
from .run import SceneRun, Timer, WarningLog
from .stages import score_view


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
    executor: None or "serial" (views scored here, one after another), "ray"
        (uncached views scored as Ray tasks, :mod:`.distributed`; needs the
        ``r360gpu[ray]`` extra), or a :class:`~.distributed.RayExecutor`.
    ray_address: with executor="ray": "local" (default), "auto" or a cluster address.
    """
    from ..aggregate.pooling import aggregate_results
    from ..bundle import Bundle, load_bundle
    from ..gpu import get_context

    opts = options or EvaluateOptions()
    if executor is not None or ray_address is not None:
        from .distributed import open_executor

        executor = open_executor(executor, ray_address=ray_address, adapter=adapter, device=device, log=log)
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
            results["scenes"][bundle.name] = evaluate_scene(run, cache, sink, progress, executor)
        finally:
            run.release()
        results["probes"] = run.probes_desc
        n_views_done += len(run.views)
    results["timing"] = {"stages_s": {k: round(v, 3) for k, v in timer.totals.items()},
                         "total_s": round(time.perf_counter() - t_start, 3),
                         "views": n_views_done}
    if executor is not None:  # what ran where; a comparison of runs leaves timing out
        results["timing"]["executor"] = executor.describe()
        executor.close()
    if warnings.items:
        results["warnings"] = warnings.items
    aggregate_results(results, n_boot=opts.n_boot, n_perm=opts.n_perm, seed=opts.seed)
    return results


def evaluate_scene(run: SceneRun, cache: RunCache, sink: PictureSink, progress: bool, executor=None) -> dict:
    """Every view of one scene (from the view cache where it has them); the scene's results entry."""
    from ..aggregate.results import method_axes
    from ..aggregate.validity import scene_validity
    from ..metrics.record import ViewRecord

    bundle, opts = run.bundle, run.opts
    view_cache = cache.views(bundle.name, {
        "bundle": fingerprint(bundle, [run.pre, run.reference, *run.methods.values()]),
        "options": opts.scoring_key(), "probes": run.probes_desc, "mode": run.mode, "depth": run.depth_mode,
        "lpips": run.lpips.describe() if run.lpips else None})
    scored = [*bundle.methods, *run.controls.values()]
    records: dict = {m: [] for m in scored}
    boundaries: dict = {m: [] for m in scored}
    pictures: dict = {m: {} for m in scored}
    # The executor hook: cells of the views not in the view cache come from
    # the executor (.distributed.RayExecutor), which also stores them there.
    fresh = executor.score_scene(run, view_cache, sink, progress) if executor is not None else {}
    for v in _progress(run.views, bundle.name, progress and executor is None):
        cells = fresh.pop(v, None)
        if cells is None and view_cache:
            cells = view_cache.load_scored(bundle.methods, run.controls.values(), v, pictures=sink.enabled)
        if cells is None:
            cells = score_view(run, v, sink)
            if view_cache is not None:
                for m, cell in cells.items():
                    view_cache.store(m, v, cell)
        for m, cell in cells.items():
            records[m].append(ViewRecord.from_dict(cell["record"]))
            boundaries[m].append(cell.get("boundary"))
            if cell.get("picture"):
                pictures[m][v] = cell["picture"]
        run.done(v)
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
    if run.controls:
        scene["controls"] = {c: {"source": src, "axes": method_axes(records[src], xis=opts.xis),
                                 "views": [r.to_dict() for r in records[src]]}
                             for c, src in run.controls.items()}
    scene["validity"], scene["validity_notes"], scene["detectability"] = scene_validity(scene, xi=0.3)
    return scene


def _progress(views, name, enabled):
    if not enabled:
        return views
    from tqdm import tqdm

    return tqdm(views, desc=f"scoring {name}", unit="view", dynamic_ncols=True, leave=True)
