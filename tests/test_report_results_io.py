"""results.json / results.csv: strict JSON, round trips, schema checks."""
from __future__ import annotations

import csv
import json
import math

import pytest

from r360gpu.errors import InputError
from r360gpu.metrics import json_values
from r360gpu.metrics.record import ViewRecord
from r360gpu.report.results_io import (
    RESULTS_SCHEMA,
    check_results,
    method_names,
    number,
    read_results,
    results_csv_rows,
    scene_names,
    structural_mode,
    write_results,
)

from report_fake import METHODS, SCENES, SEM_PROBE, STR_PROBE, VIEWS, fake_results, no_depth


@pytest.fixture(scope="module")
def results():
    return fake_results()


@pytest.fixture(scope="module")
def written(results, tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    return out, write_results(results, out)


def _strict(text: str):
    def bad(name):
        raise AssertionError(f"non-standard constant {name}")
    return json.loads(text, parse_constant=bad)


def test_json_is_strict_and_round_trips(results, written):
    out, (jpath, cpath) = written
    assert jpath == out / "results.json" and cpath == out / "results.csv"
    doc = _strict(jpath.read_text(encoding="utf-8"))
    assert doc == json_values.enc_tree(results)
    back = read_results(out)  # the folder works too
    assert back == doc
    assert read_results(jpath) == doc
    # the identical view keeps PSNR = +inf through the tag
    rec = next(v for v in back["scenes"]["room"]["methods"]["clean"]["views"] if v["view"] == "01")
    assert rec["fidelity"]["psnr"] == {"__float__": "inf"}
    assert number(rec["fidelity"]["psnr"]) == math.inf
    # the per-view records read back into equal ViewRecords
    for s in SCENES:
        for m in METHODS:
            for d, orig in zip(back["scenes"][s]["methods"][m]["views"], results["scenes"][s]["methods"][m]["views"]):
                assert ViewRecord.from_dict(d) == ViewRecord.from_dict(orig)
    # no temporary files left behind
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "results.json"]


def test_non_finite_axis_values_are_tagged(results, tmp_path):
    doc = json.loads(json.dumps(json_values.enc_tree(results)))
    doc["scenes"]["room"]["methods"]["clean"]["axes"]["psnr"] = math.inf
    write_results(doc, tmp_path)
    text = (tmp_path / "results.json").read_text()
    assert "Infinity" not in text
    assert number(read_results(tmp_path)["scenes"]["room"]["methods"]["clean"]["axes"]["psnr"]) == math.inf


def test_csv_has_one_row_per_view_with_exact_values(results, written):
    out, (_, cpath) = written
    with open(cpath, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(SCENES) * len(METHODS) * len(VIEWS)
    assert [(r["scene"], r["method"], r["view"]) for r in rows[:4]] == [
        ("room", "clean", "00"), ("room", "clean", "01"), ("room", "clean", "02"), ("room", "blurry", "00")]
    header, body = results_csv_rows(results)
    assert list(rows[0].keys()) == header
    for key in (f"iou_pre:{SEM_PROBE}", f"iou_post:{SEM_PROBE}", f"iou_drop:{SEM_PROBE}",
                f"detected@0.3:{SEM_PROBE}", f"detected@0.9:{SEM_PROBE}", f"sim_sam:{STR_PROBE}",
                f"s_str:{STR_PROBE}", "acc_depth", "geo_excluded", "threshold", "psnr", "ssim", "lpips"):
        assert key in header
    for r in rows:
        rec = next(v for v in results["scenes"][r["scene"]]["methods"][r["method"]]["views"] if v["view"] == r["view"])
        sem = rec["semantic"][SEM_PROBE]
        assert float(r[f"iou_post:{SEM_PROBE}"]) == sem["iou_post"]  # repr round-trips exactly
        assert float(r[f"iou_drop:{SEM_PROBE}"]) == sem["iou_drop"]
        assert r[f"detected@0.3:{SEM_PROBE}"] == ("true" if sem["iou_post"] >= 0.3 else "false")
        assert float(r[f"sim_sam:{STR_PROBE}"]) == rec["structural"][STR_PROBE]["sim_sam"]
        assert float(r["threshold"]) == rec["geometric"]["threshold"]
        assert int(r["n_no_depth_in_mask"]) == rec["geometric"]["n_no_depth_in_mask"] == no_depth(r["scene"], r["method"], r["view"])
        assert float(r["ssim"]) == rec["fidelity"]["ssim"]
    blurry = [r for r in rows if r["scene"] == "room" and r["method"] == "blurry"]
    assert [r[f"detected@0.3:{SEM_PROBE}"] for r in blurry] == ["false", "true", "true"]
    excl = next(r for r in rows if r["scene"] == "garden" and r["view"] == "02")
    assert (excl["geo_excluded"], excl["acc_depth"], excl["empty_target"]) == ("true", "", "true")
    ident = next(r for r in rows if (r["scene"], r["method"], r["view"]) == ("room", "clean", "01"))
    assert ident["psnr"] == "inf" and float(ident["psnr"]) == math.inf
    assert ident["structural_mode"] == "reference"


def test_accessors(results):
    assert scene_names(results) == list(SCENES)
    assert method_names(results) == list(METHODS)
    assert structural_mode(results, "room") == "reference"
    bare = {"scenes": {"s": {"reference": False, "methods": {"m": {"axes": {}, "views": []}}}}}
    assert structural_mode(bare, "s") == "reference_free"
    bare["scenes"]["s"]["reference"] = True
    assert structural_mode(bare, "s") == "reference"
    bare["options"] = {"reference_free": True}
    assert structural_mode(bare, "s") == "reference_free"
    assert number(None) is None and number(True) is None and number("x") is None
    assert number(3) == 3.0 and math.isnan(number({"__float__": "nan"}))
    assert number({"__float__": "bogus"}) is None


@pytest.mark.parametrize("text, fragment", [
    ("{not json", "not valid JSON (line 1"),
    ('{"schema": "r360gpu.results/1", "scenes": {}, "x": NaN}', "non-standard JSON constant NaN"),
    ('{"schema": "other/1", "scenes": {}}', "schema is 'other/1'"),
    ('[1, 2]', "expected a JSON object at the top level"),
    ('{"schema": "r360gpu.results/1", "scenes": []}', "'scenes' must be an object"),
])
def test_read_results_rejects_bad_files(tmp_path, text, fragment):
    p = tmp_path / "results.json"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        read_results(p)
    assert fragment in str(e.value)
    assert str(p) in str(e.value)


def test_read_results_lists_every_structural_problem(tmp_path):
    doc = {"schema": RESULTS_SCHEMA, "scenes": {
        "a": {"methods": {"m": {"axes": [], "views": {}}}},
        "b": {"methods": []},
    }, "aggregate": 3}
    problems = check_results(doc)
    assert len(problems) == 4
    p = tmp_path / "r.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        read_results(p)
    msg = str(e.value)
    for q in problems:
        assert q in msg
    assert "scene 'a', method 'm': 'axes' must be an object" in msg


def test_read_results_missing_file(tmp_path):
    with pytest.raises(InputError, match="results file not found"):
        read_results(tmp_path / "nope.json")
    with pytest.raises(InputError, match="results file not found"):
        read_results(tmp_path)  # a folder without results.json
