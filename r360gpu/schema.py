"""The data handed from stage to stage, typed: a view's cells, a scene's entry, the pooled cross-scene
values, the results document.

The per-view stages (:mod:`r360gpu.pipeline.stages`) return a :class:`ScoredView` per view: one
:class:`ViewCell` per method and control, and the warnings raised while scoring the view.  The
scene's schedule turns a scene's views into a :class:`SceneEntry`; the run adds its what-ifs
(orbit, residuals, pruned) as fields; the cross-scene pooling (:mod:`r360gpu.aggregate.pooling`)
returns a :class:`Pooled`; a :class:`ResultsDoc` holds them all.  Only the results document
(:mod:`r360gpu.pipeline.results_doc`) turns these into the JSON of results.json, in the order
:data:`SCENE_KEYS` gives (schema :data:`r360gpu.protocol.RESULTS_SCHEMA`).

A leaf like :mod:`r360gpu.protocol`: it imports no other r360gpu module, so every package may use it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class ViewCell:
    """One method's (or control's) measures at one view.

    record: the view's :class:`~r360gpu.metrics.record.ViewRecord` (kept as one until a cache cell
    or results.json is written); boundary: its boundary-sweep rows ({row: {label: value}}; None for
    the controls, or with the sweep off); picture: the contact sheet's path relative to the output
    folder (None without pictures, and for the controls); inputs: {path: stamp} of the precomputed
    probe files read for the view (the view cache serves the cell only while they are unchanged).
    """

    record: Any
    boundary: dict | None = None
    picture: str | None = None
    inputs: dict = field(default_factory=dict)


@dataclass
class ScoredView:
    """Every cell of one view ({method or control source: ViewCell}) and the warnings raised while
    it was scored ({"records", "counts"} of :func:`r360gpu.util.warning_log.for_view`, replayed when
    the view comes from the cache; None where no run collects them)."""

    cells: dict[str, ViewCell]
    warnings: dict | None = None


#: A scene entry's keys in the order results.json lists them (the optional ones only when set).
SCENE_KEYS = ("prompt", "n_views", "views", "reference", "structural_mode", "depth", "sources", "methods",
              "frame_check", "target", "expected", "controls", "validity", "validity_notes", "detectability",
              "notes", "orbit", "residuals", "pruned", "probes")


@dataclass
class SceneEntry:
    """One scene's entry of results.json (``scenes.S``; :data:`SCENE_KEYS` in that order).

    The header (prompt .. sources) describes the run; ``methods`` {method: {"axes", "views",
    "pictures"}} and ``controls`` {control: {"source", "axes", "views"}} hold the measures (views
    as dicts); ``validity``, ``validity_notes`` and ``detectability`` the controls' verdicts;
    ``notes`` the compat mode's notes.  ``orbit``, ``residuals`` and ``pruned`` are the what-ifs
    the run adds (``orbit``: the orbit's own :class:`SceneEntry` with its pose counts, or the pose
    counts alone, :class:`OrbitEntry`); ``probes`` the scene's probe descriptions.  An optional
    field left None is not written.
    """

    prompt: str
    n_views: int
    views: list
    reference: bool
    structural_mode: str
    depth: str
    sources: dict
    methods: dict = field(default_factory=dict)
    frame_check: dict | None = None
    target: dict | None = None
    expected: dict | None = None
    controls: dict | None = None
    validity: dict | None = None
    validity_notes: list | None = None
    detectability: dict | None = None
    notes: list | None = None
    orbit: OrbitEntry | None = None
    residuals: dict | None = None
    pruned: dict | None = None
    probes: dict | None = None


@dataclass
class OrbitEntry:
    """``scenes.S.orbit``: the orbit's poses (requested, kept, dropped, files, note: ``info``) and,
    when some pose was kept, the orbit scored like a scene (``scene``)."""

    info: dict
    scene: SceneEntry | None = None


@dataclass
class Pooled:
    """The cross-scene values of a run (:func:`r360gpu.aggregate.pooling.aggregate_results`).

    validity: {axis: [scenes where the axis is "weak" or "blind"]}; aggregate: the cross-scene
    tables (None when no method has all three axes in every scene); sensitivity: the pooled xi and
    boundary sweeps (None without tables); notes: why something was left out, with ``notes_first``
    True when they come before the tables in results.json (the methods some scene lacks).
    """

    validity: dict
    aggregate: dict | None
    sensitivity: dict | None = None
    notes: list[str] = field(default_factory=list)
    notes_first: bool = False


@dataclass
class ResultsDoc:
    """One run's results document before it is written: what it ran with, its scenes (each with the
    probes it ran: ``selection`` {scene: {axis: {"probes", "source", "why"}}}), the stage timings,
    the pooled cross-scene values and the run's warnings.  The schema tag, the version and the
    run-level probe descriptions are added where it is turned into JSON
    (:func:`r360gpu.pipeline.results_doc.results_json`)."""

    adapter: dict
    options: dict
    created: str
    scenes: dict[str, SceneEntry] = field(default_factory=dict)
    selection: dict[str, dict] = field(default_factory=dict)
    timing: dict | None = None
    pooled: Pooled | None = None
    warnings: list[dict] | None = None
    warning_counts: dict | None = None
