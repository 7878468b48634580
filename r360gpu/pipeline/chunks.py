"""Scoring a chunk of a scene's views from picklable inputs, for executors in other processes.

:func:`score_chunk` takes what can cross a process boundary (a bundle folder
or :class:`~r360gpu.bundle.Bundle` of file specs, :class:`~.options.EvaluateOptions`,
probe objects, view names) and returns plain JSON-ready cells, so a process
pool or a cluster scheduler can score the views of one scene in parallel:
each worker opens its own GPU context and :class:`~.run.SceneRun`.  Probes
that learn from the scene fit on the same views in every worker (the fit
views follow from the bundle and options, not from the chunk), so every
chunk scores with the same fitted probe.
"""
from __future__ import annotations

from ..bundle import load_bundle
from ..errors import InputError
from ..gpu import get_context
from .cache import cell_json, RunCache
from .picture_sink import PictureSink
from .run import SceneRun, Timer
from .stages import score_view


def score_chunk(bundle, options, semantic_probes, structural_probes, views, *, adapter: str | None = None,
                ctx=None) -> dict:
    """{view: {method: cell}} for ``views`` of one scene, computed in this process.

    bundle: a bundle folder or a loaded Bundle; options: EvaluateOptions
    (its ``views`` patterns select the scene's views, as :func:`~.evaluate.evaluate`
    selects them: the fit views are among them);
    views: names among the scene's views; cells as :func:`~.stages.score_view`
    gives them, written as JSON-ready dicts (:func:`~.cache.cell_json`: the record a dict) to cross
    the process boundary (no pictures, no cache: the caller owns the output folder).
    """
    ctx = ctx or get_context(adapter)
    b = load_bundle(bundle, views=list(options.views) if options.views else None)
    run = SceneRun(b, options, ctx, list(semantic_probes), list(structural_probes), cache=RunCache(None),
                   timer=Timer())
    try:
        unknown = [v for v in views if v not in run.views]
        if unknown:
            raise InputError(f"scene {b.name}: views {unknown[:5]} are not among its evaluation views")
        sink = PictureSink(None, False)
        return {v: {m: cell_json(c) for m, c in score_view(run, v, sink).cells.items()} for v in views}
    finally:
        run.release()
