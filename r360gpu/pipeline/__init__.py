"""Scoring scene bundles end to end: load -> render -> probe -> measure -> aggregate.

Read in this order:

* :mod:`.options`   -- :class:`EvaluateOptions` (the ``score`` flags) and the default probes;
* :mod:`.run`       -- :class:`~.run.SceneRun`: one scene's sources (a pre per method,
  reference, methods), target masks and probes, opened once; the timer and the warning log;
* :mod:`.stages`    -- the per-view stages: render -> probe -> measure -> picture,
  :func:`~.stages.score_view` giving one cell per method;
* :mod:`.cache`     -- the view cache (per-view cells) and the probe cache under ``OUT/.r360cache``;
* :mod:`.pictures`  -- :class:`~.pictures.PictureSink`, the contact sheets the stages feed;
* :mod:`.evaluate`  -- :func:`evaluate`: scenes in, the results document out;
* :mod:`.distributed` -- the Ray executor: uncached views scored as Ray tasks (optional ``ray``).

Pooling across scenes is :mod:`r360gpu.aggregate.pooling`; scenes built from
in-memory objects are :func:`r360gpu.bundle.scene_from_objects`.
"""
from __future__ import annotations

from .cache import CACHE_DIR
from .evaluate import evaluate
from .options import EvaluateOptions, default_probes

__all__ = ["CACHE_DIR", "EvaluateOptions", "default_probes", "evaluate"]
