"""aggregate_tables: the JSON-ready structure, pooling labels, and edge cases."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.aggregate import AxisCells, aggregate_tables, read_axes_csv

from remove360_paper import AXES_CSV, by_method

PAIRS = ["sem-geo", "sem-str", "geo-str"]


def _cells(s_sem, s_geo, s_str, scenes=None, methods=None, **kw):
    s_sem = np.asarray(s_sem, dtype=float)
    scenes = scenes or tuple(f"s{i}" for i in range(s_sem.shape[0]))
    methods = methods or tuple(f"m{j}" for j in range(s_sem.shape[1]))
    return AxisCells(scenes, methods, s_sem, np.asarray(s_geo, float), np.asarray(s_str, float), **kw)


def test_structure_and_lossless_json_round_trip():
    rng = np.random.default_rng(1)
    cells = _cells(*(rng.random((5, 3)) for _ in range(3)), iou_drop=rng.random((5, 3)) - 0.2)
    out = aggregate_tables(cells, n_boot=200, n_perm=100, seed=3)
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    assert set(out["rqs"]) == set(cells.scenes)
    assert all(set(v) == set(cells.methods) for v in out["rqs"].values())
    for m in cells.methods:
        assert set(out["overall"][m]) == {"s_sem", "s_geo", "s_str", "rqs", "iou_drop"}
        assert set(out["ranks"][m]) == {"sem", "geo", "str", "avg_rank", "med_rank", "worst_rank"}
        assert set(out["reliability"][m]) == {"mean", "sd", "min", "max", "ci_low", "ci_high", "p_beats_best"}
    assert list(out["axis_association"]) == PAIRS
    for v in out["axis_association"].values():
        assert {"rho", "rho_centred", "p_centred", "tau_mean", "tau_sd"} <= set(v)
    assert out["overall_pooling"] == "scene-macro"
    assert out["notes"] == {}
    assert out["reliability"][out["reliability_best"]]["p_beats_best"] is None
    assert out["settings"] == {"n_boot": 200, "n_perm": 100, "seed": 3, "ci_level": 0.95, "min_scenes_to_rank": 5,
                               "rank_decimals": None}


def test_deterministic():
    rng = np.random.default_rng(2)
    cells = _cells(*(rng.random((5, 4)) for _ in range(3)))
    assert aggregate_tables(cells, n_boot=500, n_perm=200) == aggregate_tables(cells, n_boot=500, n_perm=200)


def test_view_weighted_overall_by_hand():
    # one method, two scenes with 1 and 3 views
    cells = _cells([[0.2], [0.6]], [[1.0], [0.6]], [[0.4], [0.8]], n_views=[[1], [3]])
    out = aggregate_tables(cells, n_boot=10, n_perm=10)
    o = out["overall"]["m0"]
    assert out["overall_pooling"] == "view-weighted"
    assert o["s_sem"] == pytest.approx((0.2 + 3 * 0.6) / 4)
    assert o["s_geo"] == pytest.approx((1.0 + 3 * 0.6) / 4)
    assert o["s_str"] == pytest.approx((0.4 + 3 * 0.8) / 4)
    assert o["rqs"] == pytest.approx((0.5 * 0.7 * 0.7) ** (1 / 3))
    # the scene-macro statistic stays unweighted and is labelled separately
    macro = out["scene_macro"]["m0"]
    assert macro["s_sem"] == pytest.approx(0.4)
    assert macro["mean_rqs"] == pytest.approx(((0.2 * 0.4) ** (1 / 3) + (0.6 * 0.6 * 0.8) ** (1 / 3)) / 2)


def test_one_scene_omits_reliability_and_association_with_notes():
    cells = _cells([[0.9, 0.5]], [[0.5, 0.9]], [[0.0, 0.7]])
    out = aggregate_tables(cells)
    assert "reliability" not in out and "axis_association" not in out
    assert set(out["notes"]) == {"reliability", "axis_association"}
    assert out["notes"]["reliability"] == "too few scenes to rank with confidence (1 scene; at least 5 needed)"
    assert "at least two scenes" in out["notes"]["axis_association"]
    assert out["rqs"]["s0"]["m0"] == 0.0  # an axis at 0 gives RQS 0
    assert out["ranks"]["m0"]["str"] == 2.0


def test_identical_methods_and_single_method():
    same = [[0.3, 0.3], [0.8, 0.8], [0.5, 0.5], [0.1, 0.1], [0.9, 0.9]]
    out = aggregate_tables(_cells(same, same, same), n_boot=100, n_perm=50)
    assert out["ranks"]["m0"] == out["ranks"]["m1"]
    assert out["ranks"]["m0"]["avg_rank"] == 1.5
    assert out["reliability_best"] == "m0"
    assert out["reliability"]["m1"]["p_beats_best"] == 0.0
    single = aggregate_tables(_cells([[0.3], [0.8]], [[0.4], [0.5]], [[0.9], [0.1]]), n_boot=10, n_perm=10)
    assoc = single["axis_association"]["sem-geo"]
    assert assoc["rho"] == pytest.approx(1.0)
    assert assoc["rho_centred"] is None and assoc["p_centred"] is None and assoc["tau_mean"] is None
    assert json.dumps(single, allow_nan=False)


@pytest.mark.parametrize("n_scenes", [2, 3, 4])
def test_too_few_scenes_says_so_instead_of_intervals(n_scenes):
    """Below MIN_SCENES_TO_RANK scenes: no interval, no P(beats best), a note saying why and how many
    are needed; the axis association (two scenes) is still computed."""
    rng = np.random.default_rng(n_scenes)
    out = aggregate_tables(_cells(*(rng.random((n_scenes, 3)) for _ in range(3))), n_boot=100, n_perm=50)
    assert "reliability" not in out and "reliability_best" not in out
    assert out["notes"] == {"reliability": f"too few scenes to rank with confidence ({n_scenes} scenes; "
                                           f"at least 5 needed)"}
    assert "axis_association" in out
    assert json.loads(json.dumps(out, allow_nan=False)) == out


def test_rank_decimals_ranks_as_printed():
    cells = _cells([[0.8906, 0.8914]], [[0.5, 0.4]], [[0.5, 0.4]])
    assert aggregate_tables(cells)["ranks"]["m0"]["sem"] == 2.0
    assert aggregate_tables(cells, rank_decimals=3)["ranks"]["m0"]["sem"] == 1.5


def test_rejects_bad_settings():
    cells = _cells([[0.5]], [[0.5]], [[0.5]])
    with pytest.raises(ValueError):
        aggregate_tables(cells, n_boot=0)


def test_paper_grid_end_to_end():
    """From the transcribed per-scene axes: per-scene RQS, reliability and tau via the one entry point."""
    out = aggregate_tables(read_axes_csv(AXES_CSV))
    assert round(out["rqs"]["Stroller"]["GC"], 3) == 0.911
    assert round(out["rqs"]["Sofa"]["AF+i"], 3) == 0.209
    assert out["reliability_best"] == "3DGIC+i"
    rel = by_method("remove360_paper_reliability.csv")
    for m, row in out["reliability"].items():
        assert rel[m]["mean"].matches(row["mean"]) and rel[m]["sd"].matches(row["sd"])
    assert round(out["axis_association"]["sem-str"]["tau_mean"], 2) == 0.15
    # without view counts the Overall row is the scene-macro one, and says so
    assert out["overall_pooling"] == "scene-macro"
    assert out["overall"]["GC"]["s_sem"] == pytest.approx(out["scene_macro"]["GC"]["s_sem"])
