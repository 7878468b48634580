"""The results document (results.json): turned into JSON here, and only here.

The stages hand on typed values (:mod:`r360gpu.schema`): a run's :class:`~r360gpu.schema.ResultsDoc`
is filled while it goes (:class:`ResultsDocument`) and written from :func:`results_json`.

Schema :data:`r360gpu.protocol.RESULTS_SCHEMA`; top-level keys, in the order they are written::

    schema, r360gpu_version, created, adapter, options,
    probes      {"semantic": [...], "structural": [...]}: the probes of the run, described by what
                every scene shares (see :func:`run_probes`),
    scenes      {SCENE: {..., "probes": that scene's own probe descriptions, as fitted there}},
    timing, validity, aggregate, sensitivity (notes where :func:`pooled_json` puts them),
    warnings, warning_counts.

Why per scene: a probe that learns from the scene (the built-in appearance probe) is fitted
on each scene's pre renders, so its description (``fit`` counts, ``params.model_sha256``)
differs from scene to scene.  Each scene keeps its own; the run-level entry keeps, per probe,
the fields whose values all scenes share and names the others in ``varies_by_scene``.  With one
scene, or probes that fit nothing, the run-level entry is the probes' full description.
"""
from __future__ import annotations

import time
from dataclasses import replace

from .. import __version__
from ..protocol import RESULTS_SCHEMA
from ..schema import SCENE_KEYS, OrbitEntry, Pooled, ResultsDoc, SceneEntry

#: The probe kinds a description lists, in document order.
PROBE_KINDS = ("semantic", "structural")


def run_probes(per_scene: list[dict]) -> dict:
    """The run-level ``probes`` entry from each scene's descriptions (in scene order).

    A probe is matched across scenes by position and name; a field (top level or inside
    ``params``) whose value differs between scenes is left out and its dotted name listed,
    sorted, in ``varies_by_scene``.  Probes that some scene lacks are listed as the first scene
    describes them, with ``varies_by_scene: ["*"]``.
    """
    if not per_scene:
        return {}
    first = per_scene[0]
    out: dict = {}
    for kind in PROBE_KINDS:
        if kind not in first:
            continue
        probes = []
        for i, desc in enumerate(first[kind]):
            others = [s.get(kind, []) for s in per_scene[1:]]
            same = [o[i] for o in others if i < len(o) and isinstance(o[i], dict)
                    and o[i].get("name") == desc.get("name")]
            if len(same) != len(others) or not isinstance(desc, dict):
                probes.append({**desc, "varies_by_scene": ["*"]} if isinstance(desc, dict) else desc)
                continue
            probes.append(_shared(desc, same))
        out[kind] = probes
    return out


def _shared(desc: dict, others: list[dict]) -> dict:
    kept: dict = {}
    varies: list[str] = []
    for key, value in desc.items():
        if key == "params" and isinstance(value, dict):
            params = {}
            for pk, pv in value.items():
                if all(isinstance(o.get("params"), dict) and o["params"].get(pk, _MISSING) == pv for o in others):
                    params[pk] = pv
                else:
                    varies.append(f"params.{pk}")
            kept[key] = params
        elif all(o.get(key, _MISSING) == value for o in others):
            kept[key] = value
        else:
            varies.append(key)
    varies += [k for o in others for k in o if k not in desc and k not in varies]
    if varies:
        kept["varies_by_scene"] = sorted(set(varies))
    return kept


_MISSING = object()


class ResultsDocument:
    """One run's results document (a :class:`~r360gpu.schema.ResultsDoc`), filled in stage by stage;
    :attr:`doc` is the dict written out."""

    def __init__(self, *, adapter: dict, options: dict, created: str | None = None):
        self.data = ResultsDoc(adapter=adapter, options=options,
                               created=created or time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))

    @property
    def doc(self) -> dict:
        """The document as results.json holds it (:func:`results_json`)."""
        return results_json(self.data)

    def add_scene(self, name: str, entry: SceneEntry, probes: dict, selection: dict | None = None) -> None:
        """Scene ``name``'s entry, with its own probe descriptions; the run-level ``probes`` follow.

        selection: which probes the scene ran and why ({axis: {"probes", "source", "why"}},
        :func:`r360gpu.probes.registry.scene_probes`), kept in ``probes["selection"][name]``.
        """
        self.data.scenes[name] = replace(entry, probes=probes)
        if selection:
            self.data.selection[name] = selection

    def scene(self, name: str) -> dict:
        """Scene ``name``'s entry as results.json holds it."""
        return scene_json(self.data.scenes[name])

    def set_timing(self, stages_s: dict, total_s: float, views: int, executor: dict | None = None) -> None:
        """Stage totals and wall time (seconds, rounded to ms); left out when runs are compared."""
        self.data.timing = {"stages_s": {k: round(v, 3) for k, v in stages_s.items()},
                            "total_s": round(total_s, 3), "views": views}
        if executor is not None:  # what ran where
            self.data.timing["executor"] = executor

    def aggregate(self, *, n_boot: int, n_perm: int, seed: int) -> None:
        """The cross-scene tables, sensitivity and validity cells (:mod:`r360gpu.aggregate.pooling`)."""
        from ..aggregate.pooling import aggregate_results

        scenes = {name: scene_json(e) for name, e in self.data.scenes.items()}
        self.data.pooled = aggregate_results(scenes, n_boot=n_boot, n_perm=n_perm, seed=seed)

    def set_warnings(self, records: list[dict], counts: dict) -> None:
        self.data.warnings, self.data.warning_counts = records, counts


def results_json(d: ResultsDoc) -> dict:
    """The results document as results.json holds it (the module docstring's keys, in that order)."""
    doc = {"schema": RESULTS_SCHEMA, "r360gpu_version": __version__, "created": d.created, "adapter": d.adapter,
           "options": d.options}
    doc["probes"] = run_probes([e.probes for e in d.scenes.values()])
    if d.selection:
        doc["probes"]["selection"] = dict(d.selection)
    doc["scenes"] = {name: scene_json(e) for name, e in d.scenes.items()}
    if d.timing is not None:
        doc["timing"] = d.timing
    if d.pooled is not None:
        doc.update(pooled_json(d.pooled))
    if d.warnings is not None:
        doc["warnings"], doc["warning_counts"] = d.warnings, d.warning_counts
    return doc


#: The scene entry's fields written even when None; the others only when set.
_ALWAYS = {"prompt", "n_views", "views", "reference", "structural_mode", "depth", "sources", "methods", "validity",
           "validity_notes", "detectability"}


def scene_json(e: SceneEntry) -> dict:
    """A scene's entry as results.json holds it (:data:`r360gpu.schema.SCENE_KEYS`, in that order); the
    orbit's own scene entry with its pose counts after it."""
    out = {}
    for key in SCENE_KEYS:
        value = getattr(e, key)
        if isinstance(value, OrbitEntry):
            value = {**(scene_json(value.scene) if value.scene is not None else {}), **value.info}
        if value is not None or key in _ALWAYS:
            out[key] = value
    return out


def pooled_json(p: Pooled) -> dict:
    """The run's cross-scene values as results.json holds them: validity, aggregate, sensitivity (when
    there are tables), notes (before the tables when they name methods some scene lacks)."""
    out: dict = {"validity": p.validity}
    if p.notes and p.notes_first:
        out["notes"] = p.notes
    out["aggregate"] = p.aggregate
    if p.notes and not p.notes_first:
        out["notes"] = p.notes
    if p.sensitivity is not None:
        out["sensitivity"] = p.sensitivity
    return out
