"""The typed stage values (r360gpu.schema) turned into results.json's JSON by pipeline/results_doc.py:
keys in the document's order, optional fields left out when unset, the fields always written kept
when None, the orbit's scene with its pose counts after it, the pooled notes before or after the
tables."""
from __future__ import annotations

from r360gpu.pipeline.results_doc import ResultsDocument, pooled_json, results_json, scene_json
from r360gpu.protocol import RESULTS_SCHEMA
from r360gpu.schema import SCENE_KEYS, OrbitEntry, Pooled, ResultsDoc, SceneEntry


def _entry(**kw) -> SceneEntry:
    return SceneEntry(prompt="sofa", n_views=1, views=["v"], reference=True, structural_mode="reference",
                      depth="expected", sources={"pre": "a.ply"}, **kw)


def test_a_bare_scene_has_the_header_methods_and_verdicts_only():
    got = scene_json(_entry(methods={"m": {"axes": {}}}))
    assert list(got) == ["prompt", "n_views", "views", "reference", "structural_mode", "depth", "sources", "methods",
                         "validity", "validity_notes", "detectability"]
    assert got["validity"] is None and got["methods"] == {"m": {"axes": {}}}


def test_every_field_set_comes_in_scene_key_order():
    every = {k: {"k": k} for k in SCENE_KEYS[SCENE_KEYS.index("frame_check"):]}
    every["orbit"] = OrbitEntry({"requested": 4, "kept": 0, "note": "no orbit"})
    got = scene_json(_entry(**{k: v for k, v in every.items() if k != "methods"}))
    assert list(got) == list(SCENE_KEYS)
    assert got["orbit"] == {"requested": 4, "kept": 0, "note": "no orbit"}


def test_the_orbit_scene_comes_before_its_pose_counts():
    orbit = OrbitEntry({"requested": 8, "kept": 6}, _entry(validity={"s_sem": "ok"}))
    got = scene_json(_entry(orbit=orbit))["orbit"]
    assert list(got) == ["prompt", "n_views", "views", "reference", "structural_mode", "depth", "sources", "methods",
                         "validity", "validity_notes", "detectability", "requested", "kept"]
    assert "probes" not in got  # a what-if's scene has no probe entry of its own


def test_pooled_notes_go_before_the_tables_only_when_they_name_missing_methods():
    assert list(pooled_json(Pooled({}, {"t": 1}, {"xi": {}}))) == ["validity", "aggregate", "sensitivity"]
    assert list(pooled_json(Pooled({}, {"t": 1}, {"xi": {}}, ["left out"], notes_first=True))) == [
        "validity", "notes", "aggregate", "sensitivity"]
    assert list(pooled_json(Pooled({}, None, None, ["no tables"]))) == ["validity", "aggregate", "notes"]
    both = pooled_json(Pooled({}, None, None, ["left out", "no tables"], notes_first=True))
    assert list(both) == ["validity", "notes", "aggregate"] and both["notes"] == ["left out", "no tables"]


def test_the_document_in_order_with_each_scenes_probes():
    doc = ResultsDocument(adapter={"name": "x"}, options={"seed": 0}, created="2026-01-01T00:00:00Z")
    doc.add_scene("room", _entry(), {"semantic": [{"name": "p"}]}, selection={"semantic": {"probes": ["p"]}})
    doc.set_timing({"render": 1.0}, 2.0, 1)
    doc.data.pooled = Pooled({"s_sem": []}, None, None, ["no tables"])
    doc.set_warnings([], {})
    d = doc.doc
    assert list(d) == ["schema", "r360gpu_version", "created", "adapter", "options", "probes", "scenes", "timing",
                       "validity", "aggregate", "notes", "warnings", "warning_counts"]
    assert d["schema"] == RESULTS_SCHEMA and d["scenes"]["room"]["probes"] == {"semantic": [{"name": "p"}]}
    assert list(d["scenes"]["room"])[-1] == "probes"
    assert d["probes"] == {"semantic": [{"name": "p"}], "selection": {"room": {"semantic": {"probes": ["p"]}}}}
    assert d == results_json(doc.data) and doc.scene("room") == d["scenes"]["room"]


def test_an_empty_document_has_no_run_values_yet():
    d = results_json(ResultsDoc(adapter={}, options={}, created="c"))
    assert list(d) == ["schema", "r360gpu_version", "created", "adapter", "options", "probes", "scenes"]
    assert d["probes"] == {} and d["scenes"] == {}
