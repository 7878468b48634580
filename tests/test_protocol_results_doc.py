"""The results document keeps each scene's probe descriptions: with several scenes, results["probes"]
holds every scene's, not only the last scene's, each fitted probe with its own model hash."""
from __future__ import annotations

import json

import pytest

from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.pipeline.results_doc import ResultsDocument, run_probes
from r360gpu.schema import SceneEntry
from r360gpu.protocol import RESULTS_SCHEMA


def _desc(sha: str, images: int, name: str = "builtin-appearance") -> dict:
    return {"semantic": [{"name": name, "kind": "semantic", "weight_free": True,
                          "params": {"colour_bins": [8, 16, 16], "model_sha256": sha},
                          "fit": {"images": images}}],
            "structural": [{"name": "builtin-graphseg", "kind": "structural", "params": {"k": 300}}]}


def test_run_probes_keeps_what_every_scene_shares_and_names_the_rest():
    a, b = _desc("aa", 4), _desc("bb", 4)
    run = run_probes([a, b])
    sem = run["semantic"][0]
    assert sem["params"] == {"colour_bins": [8, 16, 16]} and sem["fit"] == {"images": 4}
    assert sem["varies_by_scene"] == ["params.model_sha256"]
    assert run["structural"] == a["structural"]  # identical in both: the full description, nothing marked
    assert run_probes([a]) == a  # one scene: its description as it is
    c = _desc("aa", 6)
    assert run_probes([a, c])["semantic"][0]["varies_by_scene"] == ["fit"]
    other = _desc("aa", 4, name="other-probe")
    assert run_probes([a, other])["semantic"][0]["varies_by_scene"] == ["*"]
    assert run_probes([]) == {}


def test_document_keeps_each_scenes_probes_and_a_meaningful_run_entry():
    doc = ResultsDocument(adapter={"name": "x"}, options={"seed": 0}, created="2026-01-01T00:00:00Z")
    entry = SceneEntry(prompt="p", n_views=0, views=[], reference=False, structural_mode="reference_free",
                       depth="expected", sources={})
    doc.add_scene("room", entry, _desc("aa", 4))
    doc.add_scene("garden", entry, _desc("bb", 4))
    d = doc.doc
    assert d["schema"] == RESULTS_SCHEMA
    assert d["scenes"]["room"]["probes"]["semantic"][0]["params"]["model_sha256"] == "aa"
    assert d["scenes"]["garden"]["probes"]["semantic"][0]["params"]["model_sha256"] == "bb"
    assert "model_sha256" not in d["probes"]["semantic"][0]["params"]
    doc.set_timing({"render": 1.23456}, 2.0, 8, executor={"kind": "ray"})
    d = doc.doc
    assert d["timing"] == {"stages_s": {"render": 1.235}, "total_s": 2.0, "views": 8, "executor": {"kind": "ray"}}
    assert list(d)[:7] == ["schema", "r360gpu_version", "created", "adapter", "options", "probes", "scenes"]


@pytest.fixture(scope="module")
def two_scenes(tmp_path_factory, ctx):
    from r360gpu.synthetic import generate_benchmark

    root = tmp_path_factory.mktemp("two")
    folders = generate_benchmark(root / "b", n_views=4, width=64, height=48, scenes=("room", "garden"),
                                 detail=0.08, ctx=ctx)
    out = root / "out"
    res = evaluate(folders, out=out, options=EvaluateOptions(n_boot=50, n_perm=20, pictures=False), device=ctx,
                   progress=False, log=lambda *a: None)
    return res, out


def test_two_scenes_with_different_fitted_probes_keep_both_descriptions(two_scenes, ctx):
    res, out = two_scenes
    room = res["scenes"]["room"]["probes"]["semantic"][0]
    garden = res["scenes"]["garden"]["probes"]["semantic"][0]
    # the appearance probe is fitted on each scene: two different models
    assert room["name"] == garden["name"] == "builtin-appearance"
    assert room["params"]["model_sha256"] != garden["params"]["model_sha256"]
    run = res["probes"]["semantic"][0]
    assert "params.model_sha256" in run["varies_by_scene"] and "model_sha256" not in run["params"]
    assert run["params"]["colour_bins"] == room["params"]["colour_bins"]
    # written as returned, and the viewer's reader picks each scene's own
    stored = json.loads((out / "results.json").read_text())
    assert stored["scenes"]["garden"]["probes"] == res["scenes"]["garden"]["probes"]
    from r360gpu.viewer.results import load_results

    for scene in ("room", "garden"):
        got = load_results(out / "results.json", scene).probes["semantic"][0]
        assert got["params"]["model_sha256"] == res["scenes"][scene]["probes"]["semantic"][0]["params"]["model_sha256"]
    # the report lists the run's probes and says what varies by scene
    html = (out / "report.html").read_text()
    assert "builtin-appearance" in html and "params.model_sha256" in html
