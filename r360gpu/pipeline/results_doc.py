"""The results document (results.json): built here, and only here, while a run goes.

Schema :data:`r360gpu.protocol.RESULTS_SCHEMA`; top-level keys, in the order they are written::

    schema, r360gpu_version, created, adapter, options,
    probes      {"semantic": [...], "structural": [...]}: the probes of the run, described by what
                every scene shares (see :func:`run_probes`),
    scenes      {SCENE: {..., "probes": that scene's own probe descriptions, as fitted there}},
    timing, validity, aggregate, sensitivity, [notes,] warnings, warning_counts.

Why per scene: a probe that learns from the scene (the built-in appearance probe) is fitted
on each scene's pre renders, so its description (``fit`` counts, ``params.model_sha256``)
differs from scene to scene.  Each scene keeps its own; the run-level entry keeps, per probe,
the fields whose values all scenes share and names the others in ``varies_by_scene``.  With one
scene, or probes that fit nothing, the run-level entry is the probes' full description.
"""
from __future__ import annotations

import time

from .. import __version__
from ..protocol import RESULTS_SCHEMA

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
    """One run's results document, filled in stage by stage; :attr:`doc` is the dict written out."""

    def __init__(self, *, adapter: dict, options: dict, created: str | None = None):
        self.doc: dict = {
            "schema": RESULTS_SCHEMA,
            "r360gpu_version": __version__,
            "created": created or time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            "adapter": adapter,
            "options": options,
            "probes": {},
            "scenes": {},
        }
        self._scene_probes: list[dict] = []
        self._selection: dict = {}

    def add_scene(self, name: str, entry: dict, probes: dict, selection: dict | None = None) -> None:
        """Scene ``name``'s entry, with its own probe descriptions; the run-level ``probes`` follow.

        selection: which probes the scene ran and why ({axis: {"probes", "source", "why"}},
        :func:`r360gpu.probes.registry.scene_probes`), kept in ``probes["selection"][name]``.
        """
        entry["probes"] = probes
        self.doc["scenes"][name] = entry
        self._scene_probes.append(probes)
        if selection:
            self._selection[name] = selection
        self.doc["probes"] = run_probes(self._scene_probes)
        if self._selection:
            self.doc["probes"]["selection"] = dict(self._selection)

    def set_timing(self, stages_s: dict, total_s: float, views: int, executor: dict | None = None) -> None:
        """Stage totals and wall time (seconds, rounded to ms); left out when runs are compared."""
        self.doc["timing"] = {"stages_s": {k: round(v, 3) for k, v in stages_s.items()},
                              "total_s": round(total_s, 3), "views": views}
        if executor is not None:  # what ran where
            self.doc["timing"]["executor"] = executor

    def aggregate(self, *, n_boot: int, n_perm: int, seed: int) -> None:
        """The cross-scene tables, sensitivity and validity cells (:mod:`r360gpu.aggregate.pooling`)."""
        from ..aggregate.pooling import aggregate_results

        aggregate_results(self.doc, n_boot=n_boot, n_perm=n_perm, seed=seed)

    def set_warnings(self, records: list[dict], counts: dict) -> None:
        self.doc["warnings"] = records
        self.doc["warning_counts"] = counts
