"""Compatibility: the scoring entry points now live in :mod:`r360gpu.pipeline`
(and :func:`r360gpu.bundle.scene_from_objects`)."""
from __future__ import annotations

from .bundle.objects import scene_from_objects
from .pipeline import CACHE_DIR, EvaluateOptions, default_probes, evaluate

__all__ = ["CACHE_DIR", "EvaluateOptions", "default_probes", "evaluate", "scene_from_objects"]
