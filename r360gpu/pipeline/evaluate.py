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
    for line in missing_methods(loaded):
        log(f"note: {line}")
    out = Path(out) if out is not None else None
    cache = RunCache(out, force=force)
    sink = PictureSink(out, opts.pictures, ctx=ctx)
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
    if out is not None:
        from ..report.outputs import write_outputs

        write_outputs(results, out)
    return results


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


def evaluate_scene(run: SceneRun, cache: RunCache, sink: PictureSink, progress: bool) -> dict:
    """Every view of one scene (from the view cache where it has them); the scene's results entry."""
    from ..aggregate.results import method_axes
    from ..metrics.record import ViewRecord

    bundle, opts = run.bundle, run.opts
    view_cache = cache.views(bundle.name, {
        "bundle": fingerprint(bundle, [*run.pres.values(), run.reference, *run.methods.values()]),
        "options": opts.scoring_key(), "probes": run.probes_desc, "mode": run.mode, "depth": run.depth_mode,
        "lpips": run.lpips.describe() if run.lpips else None})
    records: dict = {m: [] for m in bundle.methods}
    boundaries: dict = {m: [] for m in bundle.methods}
    pictures: dict = {m: {} for m in bundle.methods}
    for v in _progress(run.views, bundle.name, progress):
        cells = view_cache.load_view(bundle.methods, v, pictures=sink.enabled) if view_cache else None
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
    return scene


def _progress(views, name, enabled):
    from ..util.progress import progress

    return progress(views, desc=f"scoring {name}", unit="view", enabled=enabled)
