"""The parts of a ``results.json`` (``r360gpu score``) the viewer shows for one scene.

Per method: the scene-level axes (s_sem, s_geo, s_str, RQS) and, per
evaluation view, the per-view axes from the view records:

* ``s_sem``: 1 when the object is no longer detected on I_post at
  ξ = 0.3 (IoU_post < 0.3), else 0 — over several semantic probes the most
  alarming reading (highest IoU_post), as the scene axis uses;
* ``iou_post``, ``iou_drop``: that reading's IoUs;
* ``s_geo``: acc_depth of the view (None when its target mask is empty);
* ``s_str``: the structural score of the view, lowest over the probes.

Also the probes' ``describe()`` entries (to find cached probe masks) and
where the probe cache is (``<results folder>/.r360cache/probes``).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from r360gpu.errors import InputError
from r360gpu.pipeline import CACHE_DIR  # where ``r360gpu score`` keeps its caches, beside results.json
from r360gpu.metrics.record import ViewRecord
from r360gpu.protocol import AXES, RESULTS_SCHEMA as SCHEMA, XI_DEFAULT  # AXES: per-view axes in chart order


@dataclass(frozen=True)
class ViewAxes:
    """Per-view values of one (method, view); None where not measured."""

    s_sem: float | None
    iou_post: float | None
    iou_drop: float | None
    s_geo: float | None
    s_str: float | None

    def get(self, axis: str) -> float | None:
        return getattr(self, axis)


@dataclass
class MethodResults:
    """Scene-level ``axes`` (the results file's dict) and per-view values by view name."""

    axes: dict
    views: dict[str, ViewAxes] = field(default_factory=dict)

    def worst_view(self, view_names: list[str]) -> str | None:
        """The view of ``view_names`` with the lowest mean of its per-view axes (s_sem 0/1, s_geo,
        s_str; the report's "leaks most" order), first on ties; None when no view has values."""
        best, best_mean = None, None
        for v in view_names:
            va = self.views.get(v)
            vals = [] if va is None else [x for x in (va.s_sem, va.s_geo, va.s_str)
                                          if x is not None and x == x]
            if vals and (best_mean is None or sum(vals) / len(vals) < best_mean):
                best, best_mean = v, sum(vals) / len(vals)
        return best

    def series(self, axis: str, view_names: list[str]) -> list[float]:
        """Values of ``axis`` along ``view_names`` (NaN where missing), for charts."""
        out = []
        for v in view_names:
            va = self.views.get(v)
            x = va.get(axis) if va is not None else None
            out.append(float("nan") if x is None else float(x))
        return out


@dataclass
class SceneResults:
    """One scene of a results file."""

    path: Path
    scene: str
    methods: dict[str, MethodResults]
    probes: dict[str, list[dict]]
    prompt: str | None
    residuals: dict = field(default_factory=dict)  # {method: residuals PLY path} (score --residuals)

    @property
    def probe_cache(self) -> Path:
        """The probe cache folder of the run that wrote the file."""
        return self.path.parent / CACHE_DIR / "probes"


def _finite(x) -> float | None:
    if x is None or isinstance(x, bool):
        return None
    try:
        f = float(x)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def view_axes(record: ViewRecord) -> ViewAxes:
    """Per-view axes of one record (see the module docstring)."""
    s_sem = iou_post = iou_drop = None
    if record.semantic:
        worst = max(record.semantic.values(), key=lambda s: s.iou_post)
        iou_post, iou_drop = float(worst.iou_post), float(worst.iou_drop)
        s_sem = None if worst.empty_target else (0.0 if worst.detected(XI_DEFAULT) else 1.0)
    s_str = None
    if record.structural:
        scores = [s.s_str for s in record.structural.values() if not s.empty_target]
        s_str = float(min(scores)) if scores else None
    s_geo = _finite((record.geometric or {}).get("acc_depth"))
    return ViewAxes(s_sem, iou_post, iou_drop, s_geo, s_str)


def load_results(path, scene: str) -> SceneResults:
    """Read ``path`` (results.json) and pick ``scene``; InputError naming the file otherwise."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise InputError(f"cannot read the results file ({e.strerror or e})", path) from None
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON ({e.msg} at line {e.lineno})", path) from None
    if not isinstance(doc, dict) or doc.get("schema") != SCHEMA:
        got = doc.get("schema") if isinstance(doc, dict) else type(doc).__name__
        raise InputError(f"not an r360gpu results file (schema {got!r}, expected {SCHEMA!r})", path)
    scenes = doc.get("scenes")
    if not isinstance(scenes, dict) or scene not in scenes:
        have = ", ".join(sorted(scenes)) if isinstance(scenes, dict) else "none"
        raise InputError(f"has no scene {scene!r} (scenes: {have})", path)
    entry = scenes[scene]
    methods = {}
    for name, m in (entry.get("methods") or {}).items():
        views = {}
        for i, rec in enumerate(m.get("views") or []):
            try:
                r = ViewRecord.from_dict(rec)
            except (InputError, KeyError, TypeError, ValueError) as e:
                raise InputError(f"scene {scene!r}, method {name!r}, view record {i}: {e}", path) from None
            views[r.view] = view_axes(r)
        methods[str(name)] = MethodResults(axes=dict(m.get("axes") or {}), views=views)
    probes = entry.get("probes") or doc.get("probes") or {}  # the scene's own (fitted there), else the run's
    residuals = {str(m): path.parent / r["file"] for m, r in (entry.get("residuals") or {}).items()
                 if isinstance(r, dict) and isinstance(r.get("file"), str)}
    return SceneResults(path=path, scene=scene, methods=methods,
                        probes={k: list(probes.get(k) or []) for k in ("semantic", "structural")},
                        prompt=entry.get("prompt"), residuals=residuals)
