"""``r360gpu tables``: JSON structure, printed tables, and exit code 2 on bad CSVs."""
from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import r360gpu.cli as cli

from remove360_paper import AXES_CSV, METHODS, by_method

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def only_tables_command(monkeypatch):
    # Run the real main() with just this sub-command registered, so these
    # tests do not depend on the other sub-commands' modules.
    monkeypatch.setattr(cli, "_COMMANDS", ["tables"])


def _run(capsys, *argv):
    rc = cli.main(["tables", *map(str, argv)])
    out, err = capsys.readouterr()
    return rc, out, err


def _check_structure(data: dict, scenes: list[str], methods: list[str], with_stats: bool) -> None:
    assert list(data["rqs"]) == scenes
    for s in scenes:
        assert list(data["rqs"][s]) == methods
        assert all(isinstance(v, float) for v in data["rqs"][s].values())
    assert list(data["overall"]) == methods
    assert list(data["ranks"]) == methods
    for m in methods:
        assert {"s_sem", "s_geo", "s_str", "rqs"} <= set(data["overall"][m])
        assert all(isinstance(data["overall"][m][k], float) for k in ("s_sem", "s_geo", "s_str", "rqs"))
        assert set(data["ranks"][m]) == {"sem", "geo", "str", "avg_rank", "med_rank", "worst_rank"}
    if not with_stats:
        assert "reliability" not in data and "axis_association" not in data
        return
    assert list(data["reliability"]) == methods
    for m in methods:
        row = data["reliability"][m]
        assert {"mean", "sd", "min", "max", "ci_low", "ci_high", "p_beats_best"} <= set(row)
        assert row["p_beats_best"] is None or isinstance(row["p_beats_best"], float)
    assert list(data["axis_association"]) == ["sem-geo", "sem-str", "geo-str"]
    for v in data["axis_association"].values():
        assert {"rho", "rho_centred", "p_centred", "tau_mean", "tau_sd"} <= set(v)


def test_paper_csv_json_and_markdown(tmp_path, capsys):
    out_json = tmp_path / "sub" / "agg.json"
    rc, out, err = _run(capsys, AXES_CSV, "--json", out_json, "--n-boot", 20000, "--n-perm", 500)
    assert rc == 0, err
    data = json.loads(out_json.read_text())
    scenes = list(data["scenes"])
    assert len(scenes) == 11
    _check_structure(data, scenes, list(METHODS), with_stats=True)
    assert round(data["rqs"]["Sofa"]["OC"], 3) == 0.574
    assert data["reliability"]["3DGIC+i"]["p_beats_best"] is None
    assert round(data["reliability"]["GC"]["p_beats_best"], 3) == 0.266  # seed 0, 20,000 resamples
    assert data["overall_pooling"] == "scene-macro"
    assert not list(tmp_path.glob("sub/.*tmp"))  # atomic write left no temp file
    assert "**Per-scene Removal Quality Score" in out and "| Sofa |" in out
    assert "**Reliability" in out and "P(beats 3DGIC+i)" in out


def test_latex_output(capsys):
    rc, out, _ = _run(capsys, AXES_CSV, "--format", "latex", "--n-boot", 200, "--n-perm", 100)
    assert rc == 0
    assert out.count(r"\begin{table}") == 6 and out.count(r"\end{table}") == 6
    assert r"\label{tab:r360_rank_agg}" in out


def test_overall_rows_as_one_scene_reproduce_main_results(tmp_path, capsys):
    """The printed Overall axes as a one-scene CSV: RQS and AvgRank of tab:main_results, notes for the rest."""
    overall = by_method("remove360_paper_overall.csv")
    csv_path = tmp_path / "overall.csv"
    csv_path.write_text("scene,method,s_sem,s_geo,s_str,iou_drop\n" + "".join(
        f"Overall,{m},{r['s_sem'].value},{r['s_geo'].value},{r['s_str'].value},{r['iou_drop'].value}\n"
        for m, r in overall.items()))
    out_json = tmp_path / "o.json"
    rc, out, _ = _run(capsys, csv_path, "--json", out_json)
    assert rc == 0
    data = json.loads(out_json.read_text())
    _check_structure(data, ["Overall"], list(METHODS), with_stats=False)
    for m, row in overall.items():
        assert row["rqs"].matches(data["overall"][m]["rqs"]), m
        assert row["avg_rank"].matches(data["ranks"][m]["avg_rank"]), m
        assert data["overall"][m]["iou_drop"] == pytest.approx(row["iou_drop"].value)
    assert set(data["notes"]) == {"reliability", "axis_association"}
    assert "Note: too few scenes to rank with confidence (1 scene; at least 5 needed)" in out


def test_n_views_gives_view_weighted_overall(tmp_path, capsys):
    csv_path = tmp_path / "w.csv"
    csv_path.write_text("scene,method,s_sem,s_geo,s_str,n_views\n"
                        "a,X,0.2,0.5,0.5,1\nb,X,0.6,0.5,0.5,3\na,Y,0.5,0.5,0.5,1\nb,Y,0.5,0.5,0.5,3\n")
    out_json = tmp_path / "w.json"
    rc, out, _ = _run(capsys, csv_path, "--json", out_json, "--n-boot", 100, "--n-perm", 100)
    assert rc == 0
    data = json.loads(out_json.read_text())
    assert data["overall_pooling"] == "view-weighted"
    assert data["overall"]["X"]["s_sem"] == pytest.approx(0.5)
    assert data["scene_macro"]["X"]["s_sem"] == pytest.approx(0.4)
    assert "Overall (view-weighted)" in out


def test_seed_option_is_deterministic(tmp_path, capsys):
    paths = [tmp_path / "a.json", tmp_path / "b.json", tmp_path / "c.json"]
    for path, seed in zip(paths, (4, 4, 5)):
        assert _run(capsys, AXES_CSV, "--json", path, "--seed", seed, "--n-boot", 300, "--n-perm", 100)[0] == 0
    a, b, c = (json.loads(p.read_text()) for p in paths)
    assert a == b
    assert a["reliability"] != c["reliability"]


@pytest.mark.parametrize("text", [
    "scene,method,s_sem,s_str\nx,A,0.1,0.2\n",
    "scene,method,s_sem,s_geo,s_str\nx,A,0.1,oops,0.3\n",
    "scene,method,s_sem,s_geo,s_str\nx,A,0.1,0.2,1.3\n",
    "scene,method,s_sem,s_geo,s_str\nx,A,0.1,0.2,0.3\nx,A,0.1,0.2,0.3\n",
    "scene,method,s_sem,s_geo,s_str\nx,A,0.1,0.2,0.3\ny,B,0.1,0.2,0.3\n",
])
def test_bad_csv_exit_code_2_one_line_naming_file(tmp_path, capsys, text):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    out_json = tmp_path / "never.json"
    rc, out, err = _run(capsys, path, "--json", out_json)
    assert rc == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"r360gpu: error: {path}: ")
    assert not out_json.exists()


def test_missing_file_exit_code_2(tmp_path, capsys):
    rc, _, err = _run(capsys, tmp_path / "nope.csv")
    assert rc == 2 and str(tmp_path / "nope.csv") in err and len(err.strip().splitlines()) == 1


def test_bad_options_are_usage_errors(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["tables", str(AXES_CSV), "--n-boot", "0"])
    assert e.value.code == 2
    with pytest.raises(SystemExit):
        cli.main(["tables", str(AXES_CSV), "--format", "html"])
    capsys.readouterr()


@pytest.mark.skipif(importlib.util.find_spec("r360gpu.cli.doctor") is None,
                    reason="python -m r360gpu needs every sub-command module (cli/doctor.py not present yet)")
def test_python_dash_m_entry_point(tmp_path):
    out_json = tmp_path / "m.json"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-m", "r360gpu", "tables", str(AXES_CSV), "--json", str(out_json),
                           "--n-boot", "200", "--n-perm", "100"], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(out_json.read_text())["overall_pooling"] == "scene-macro"


def test_paper_axes_print_that_the_overall_row_is_view_weighted(tmp_path, capsys):
    from pathlib import Path

    from r360gpu.cli.tables import OVERALL_NOTE

    paper = Path(__file__).parent / "data" / "remove360_paper_axes.csv"
    out_json = tmp_path / "t.json"
    assert cli.main(["tables", str(paper), "--n-boot", "50", "--n-perm", "50", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "tab:main_results" in out and "view-weighted" in out and out.count(OVERALL_NOTE) == 1
    assert json.loads(out_json.read_text())["notes"]["overall_pooling"] == OVERALL_NOTE
