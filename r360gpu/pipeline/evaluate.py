"""evaluate(): scenes in, the results document out."""
from __future__ import annotations

import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..gpu import get_context
from ..probes.registry import scene_probes
from ..schema import SceneEntry
from ..util import warning_log
from ..util.imports import ImportAhead
from .cache import RunCache
from .distributed import open_executor
from .options import EvaluateOptions, default_probes
from .picture_sink import PictureSink
from .results_doc import ResultsDocument
from .run import SceneRun, Timer
from .schedule import evaluate_scene, host_threads


def evaluate(
    bundles,
    *,
    out=None,
    options: EvaluateOptions | None = None,
    semantic_probes=None,
    structural_probes=None,
    device=None,
    executor=None,
    force: bool = False,
    progress: bool = True,
    log=print,
) -> dict:
    """Score one or more scene bundles; returns the results document (a dict).

    bundles: bundle folders, `Bundle` objects, or
        scenes built from in-memory objects with
        `scene_from_objects` (Gaussians, or renders and
        depths already on the device).
    out: output folder: results.json, results.csv, tables.md/.tex, pictures,
        plots and report.html are written there, as ``r360gpu score`` does,
        and the per-view cache is kept there (None: nothing is written and
        nothing is cached).
    options: the scoring options (`EvaluateOptions`; None: the defaults).
    semantic_probes, structural_probes: lists of probes (default: the
        weight-free built-ins).  With several probes per axis the axes use the
        "most alarming" reading per view; each probe's own axes are kept.
    device: where the views are rendered and scored: None (the default adapter), an adapter
        choice as ``--adapter`` takes it ("auto", "gpu", "gpu:N", "cpu", part of a name), a
        caller's ``wgpu.GPUDevice``, or a context from `r360gpu.gpu.get_context`.
    executor: None or "serial" (views scored here, overlapped), "ray"
        (uncached views scored as Ray tasks on a local Ray, `.distributed`; needs the
        ``r360gpu[ray]`` extra), a `RayExecutor` (``RayExecutor(RayOptions(address="auto"))``
        for a cluster), or a `ProcessExecutor` (worker processes on this machine).
    force: recompute everything (the cache under ``out`` is cleared first).
    progress: progress bars while views are scored.
    log: where notes are said (the probes a public folder runs, moved frames, missing methods).
    """
    # One collector from the first file read: warnings of loading (a COLMAP model's distortion,
    # a BOM in prompt.txt) reach results.json as the pipeline's do.
    with warning_log.collecting():
        plan = Plan.open(out=out, options=options, semantic_probes=semantic_probes,
                         structural_probes=structural_probes, device=device, executor=executor,
                         progress=progress, log=log)
        return evaluate_plan(bundles, plan, force=force)


@dataclass(frozen=True)
class Plan:
    """What one evaluate() call runs with, built once from the caller's arguments (`Plan.open`):
    the options, the opened GPU context and executor, and the probes.

    semantic / structural: the probes given for an axis, used for every scene; None lets each
    scene take its folder's probe outputs or ``defaults``.
    kept: renders made before on ``ctx`` (`KeptRenders`, as ``r360gpu demo`` keeps the
    generator's reference renders), used where they are exactly what would be rendered; emptied
    when the run ends.
    """

    opts: EvaluateOptions
    ctx: Any
    semantic: list | None
    structural: list | None
    defaults: tuple | None
    out: Path | None
    progress: bool
    log: Callable[[str], Any]
    executor: Any = None
    kept: Any = None

    @classmethod
    def open(cls, *, out=None, options=None, semantic_probes=None, structural_probes=None, device=None,
             executor=None, progress=True, log=print, kept=None) -> Plan:
        """The plan of `evaluate`'s arguments (see there), the options checked and the
        executor and GPU context opened; ``kept`` as `Plan` has it."""
        opts = options or EvaluateOptions()
        opts._check()  # before any work, also when a field was changed after the options were built
        host_threads()  # R360GPU_HOST_THREADS too
        if executor is not None:
            executor = open_executor(executor, device=device, log=log)
        # None: not given; each scene then takes its folder's probe outputs or the defaults
        # (probes.registry.scene_probes)
        defaults = default_probes() if semantic_probes is None or structural_probes is None else None
        return cls(opts=opts, ctx=_context(device), semantic=semantic_probes, structural=structural_probes,
                   defaults=defaults, out=Path(out) if out is not None else None, progress=progress, log=log,
                   executor=executor, kept=kept)

    def scene_probes(self, bundle, compat) -> tuple:
        """(semantic, structural, selection) of ``bundle`` (`r360gpu.probes.registry.scene_probes`)."""
        return scene_probes(bundle, self.semantic, self.structural, compat=compat, defaults=self.defaults)


def _context(device):
    """The GPU context of evaluate()'s ``device`` (an adapter choice, a device or a context)."""
    if device is None or isinstance(device, str):
        return get_context(device)
    return get_context(None, device=device)


def evaluate_plan(bundles, plan: Plan, *, force: bool = False) -> dict:
    """`evaluate` with its plan already opened (`Plan.open`): what ``r360gpu score`` runs,
    with the demo's kept renders in ``plan.kept``."""
    with warning_log.collecting():
        return _load_and_evaluate(bundles, plan, force=force)


def _load_and_evaluate(bundles, plan: Plan, *, force: bool) -> dict:
    from ..bundle import Bundle, load_bundle

    opts, log = plan.opts, plan.log
    if isinstance(bundles, (str, Path, Bundle)):
        bundles = [bundles]
    # --views, applied here and only here: a folder is loaded with it (checked as `check --views` does),
    # a Bundle object narrowed to it unless loaded with it (bundle.views.narrow_views)
    sel = list(opts.views) if opts.views else None
    loaded = [load_bundle(b, views=sel) for b in bundles]
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
    cache = RunCache(plan.out, force=force)
    sink = PictureSink(plan.out, opts.pictures, embed_cache=cache.embed)
    with warning_log.collecting():
        try:
            return _evaluate(loaded, plan, cache, sink)
        finally:
            if plan.kept is not None:
                plan.kept.clear()


def _evaluate(loaded, plan: Plan, cache: RunCache, sink: PictureSink) -> dict:
    opts, ctx, out, progress, log, executor = plan.opts, plan.ctx, plan.out, plan.progress, plan.log, plan.executor

    # the cross-scene statistics (two scenes or more) use scipy.stats, first needed once every view is scored
    later = ImportAhead(*(["scipy.stats"] if len(loaded) >= 2 else []))
    timer = Timer()
    document = ResultsDocument(adapter=ctx.describe(), options={**opts.scoring_key(), "n_boot": opts.n_boot,
                                                                "n_perm": opts.n_perm, "seed": opts.seed})
    t_start = time.perf_counter()
    n_views_done = 0
    views_of: dict = {}

    def open_run(bundle) -> SceneRun:
        sem, stru, selection = plan.scene_probes(bundle, opts.compat)
        with warning_log.where(scene=bundle.name):
            run = SceneRun(bundle, opts, ctx, sem, stru, cache=cache, timer=timer, kept=plan.kept)
        run.probe_selection = selection or {}
        return run

    def open_what_if(b, o) -> SceneRun:  # a scene seen elsewhere (orbit) or a method changed (pruned)
        sem, stru, _ = plan.scene_probes(b, o.compat)
        # no frame check: a what-if sees through the capture's cameras (checked with the scene) or poses
        # derived from them (the orbit)
        return SceneRun(b, o, ctx, sem, stru, cache=cache, timer=timer, check_frames=False)

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
            with warning_log.where(scene=bundle.name):
                target = _reusable_target(run, scene_res, out)
                what_ifs = _what_ifs(run.bundle, scene_res, plan, open_what_if,
                                     lambda r, pictures=True: evaluate_scene(r, cache, sink if pictures else quiet,
                                                                             progress, what_if=True))
            views_of[bundle.name] = {v: k for k, v in enumerate(run.views)}
            document.add_scene(bundle.name, replace(scene_res, target=target, **what_ifs), run.probes_desc,
                               selection=run.probe_selection)
            n_views_done += len(run.views)
            plots.draw(bundle.name, document.scene(bundle.name))
        document.set_timing(timer.totals, time.perf_counter() - t_start, n_views_done,
                            executor.describe() if executor is not None else None)
        if executor is not None:
            executor.close()
        later.wait()
        document.aggregate(n_boot=opts.n_boot, n_perm=opts.n_perm, seed=opts.seed)
        document.set_warnings(in_run_order(warning_log.records(), [b.name for b in loaded], views_of),
                              warning_log.counts())
        results = document.doc
        if out is not None:
            from ..report.outputs import write_run_outputs

            write_run_outputs(results, out, embed_cache=cache.embed, plots=plots.drawn())
    finally:
        scenes.close()
        plots.close()
    return results


def _what_ifs(bundle, scene_res: SceneEntry, plan: Plan, open_what_if, score) -> dict:
    """The scene beyond its capture views, as :class:`~r360gpu.schema.SceneEntry` fields: the orbit
    (``--orbit N``, ``orbit``), the residual Gaussians (``residuals``) and the unranked METHOD+pruned
    what-ifs (``pruned``)."""
    opts, ctx, out = plan.opts, plan.ctx, plan.out
    fields: dict = {}
    if opts.orbit:  # --orbit N: the scene from all around (pipeline.orbit)
        from .orbit import score_orbit

        fields["orbit"] = score_orbit(bundle, opts, open_what_if, score, ctx=ctx, warn=warning_log.warn, out=out)
    if opts.residuals or opts.prune_residuals:  # the Gaussians behind the evidence (pipeline.residuals)
        from .residuals import scene_residuals, score_pruned

        fields["residuals"], values = scene_residuals(bundle, scene_res.methods, out, ctx=ctx, xis=opts.xis,
                                                      warn=warning_log.warn)
        if opts.prune_residuals:  # the what-ifs have no contact sheets
            fields["pruned"] = score_pruned(bundle, values, opts, open_what_if, lambda r: score(r, pictures=False),
                                            out)
    return fields


def _reusable_target(run, scene_res: SceneEntry, out) -> dict | None:
    """The scene's ``target`` entry, with the paths of a ``[target]``'s lifted set and rendered masks
    written under ``out`` (pipeline.reusable) under ``files``."""
    if out is None or run.target_lifted is None or scene_res.target is None:
        return scene_res.target
    from .reusable import write_target

    rendered = {v: run.bundle.masks[v] for v in scene_res.target["rendered"]}
    return {**scene_res.target,
            "files": write_target(out, run.bundle.name, run.pre.gaussians, run.target_lifted.target, rendered,
                                  source=getattr(run.bundle.pre, "path", None))}


def _say_probes(run: SceneRun, log) -> None:
    """On the console: which probes a public folder's scene runs and why (its own outputs or not)."""
    if run.bundle.layout != "remove360":
        return
    for axis, sel in run.probe_selection.items():
        log(f"probes: {run.bundle.name} {axis}: {', '.join(sel['probes'])} ({sel['source']}) -- {sel['why']}")


def _say_frames(run: SceneRun, log) -> None:
    """On the console: the splat sources whose cameras are moved into another frame (r360gpu.io.frames)."""
    named = [("pre", run.pre), ("reference", run.reference), *run.methods.items()]
    for name, src in named:
        frame = src.frame if src is not None and src.kind == "scene" else None  # (render.sources.Source)
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
