"""Scoring scene bundles end to end: load -> render -> probe -> measure -> aggregate.

Read in this order:

* :mod:`.options`   -- :class:`EvaluateOptions` (the ``score`` flags) and the default probes;
* :mod:`.run`       -- :class:`~.run.SceneRun`: one scene's sources (a pre per method,
  reference, methods), target masks and probes, opened once; the timer and the warning log;
* :mod:`.stages`    -- the per-view stages: render -> probe -> measure -> picture, split by
  where they may run (GPU thread / any thread); :func:`~.stages.score_view` runs them in a row;
* :mod:`.cache`     -- the view cache (per-view cells), the probe cache and fit records
  under ``OUT/.r360cache``;
* :mod:`.picture_sink`  -- :class:`~.picture_sink.PictureSink`, the contact sheets the stages feed;
* :mod:`.writer`    -- :class:`~.writer.BackgroundWriter`: pictures and cache cells off the GPU thread;
* :mod:`.evaluate`  -- :func:`evaluate`: scenes in, the results document out; the views of a
  scene overlapped (GPU thread renders and measures, host threads read and probe ahead);
* :mod:`.results_doc` -- :class:`~.results_doc.ResultsDocument`: the results document, filled
  with the stages' typed values (:mod:`r360gpu.schema`) and turned into JSON in this one place
  (each scene's probe descriptions kept with the scene);
* :mod:`.chunks`    -- :func:`~.chunks.score_chunk`: a chunk of views from picklable inputs,
  for executors in other processes;
* :mod:`.distributed` -- the Ray executor: uncached views scored as Ray tasks (optional ``ray``),
  and what every executor of view chunks shares;
* :mod:`.processes` -- the same in worker processes on this machine (``--processes N``).

Pooling across scenes is :mod:`r360gpu.aggregate.pooling`; scenes built from
in-memory objects are :func:`r360gpu.bundle.scene_from_objects`.
"""
from __future__ import annotations

from .cache import CACHE_DIR
from .evaluate import evaluate
from .options import EvaluateOptions, default_probes

__all__ = ["CACHE_DIR", "EvaluateOptions", "default_probes", "evaluate"]
