"""Controls (the unedited scene and the reference scored as methods) and the validity verdicts."""
from __future__ import annotations

import pytest

from r360gpu.aggregate.validity import detectability, not_ok_cells, scene_validity
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.report.outputs import summary_lines
from r360gpu.synthetic import generate_benchmark

OPTS = dict(n_boot=200, n_perm=100, boundary=False)


@pytest.fixture(scope="module")
def bundle(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("bench")
    return generate_benchmark(root, seed=3, n_views=4, width=200, height=150, scenes=("room",), detail=0.5, ctx=ctx)[0]


@pytest.fixture(scope="module")
def with_controls(bundle, tmp_path_factory, ctx):
    out = tmp_path_factory.mktemp("out")
    return out, evaluate(bundle, out=out, options=EvaluateOptions(pictures=False, **OPTS), device=ctx, progress=False)


def test_controls_are_scored_reported_and_never_ranked(with_controls):
    _, res = with_controls
    scene = res["scenes"]["room"]
    ident, ref = scene["controls"]["identity"]["axes"], scene["controls"]["reference"]["axes"]
    # Nothing was removed from the identity control: its depth equals pre's, the probe's
    # reading of it is pre's reading, so IoU_post == IoU_pre in every view.
    assert ident["s_geo"] == 0.0
    for v in scene["controls"]["identity"]["views"]:
        for s in v["semantic"].values():
            assert s["iou_post"] == s["iou_pre"]
    # The reference is a real removal; in reference mode it is compared with itself.
    assert scene["structural_mode"] == "reference" and ref["s_str"] == 1.0
    assert ref["s_geo"] > ident["s_geo"] + 0.2
    assert set(scene["controls"]) == {"identity", "reference"}
    assert "identity" not in res["aggregate"]["overall"] and "pre" not in res["aggregate"]["overall"]
    assert set(scene["validity"]) == {"s_sem", "s_geo", "s_str"}
    assert all(v in ("ok", "weak", "blind") for v in scene["validity"].values())
    for axis, verdict in scene["validity"].items():
        assert (verdict == "ok") == (axis not in scene["validity_notes"])
    text = "\n".join(summary_lines(res))
    assert "control identity" in text and "control reference" in text and "validity" in text


def test_controls_leave_the_methods_numbers_alone(bundle, with_controls, ctx):
    _, res = with_controls
    plain = evaluate(bundle, options=EvaluateOptions(controls=False, **OPTS), device=ctx, progress=False)
    assert "controls" not in plain["scenes"]["room"]
    a = {m: e["axes"] for m, e in res["scenes"]["room"]["methods"].items()}
    b = {m: e["axes"] for m, e in plain["scenes"]["room"]["methods"].items()}
    assert a == b
    # Without controls the semantic verdict still rests on the pre-removal detectability.
    assert plain["scenes"]["room"]["validity"]["s_sem"] in ("ok", "weak", "blind")


def test_controls_come_from_the_cache_on_a_rerun(bundle, with_controls, ctx):
    out, first = with_controls
    again = evaluate(bundle, out=out, options=EvaluateOptions(pictures=False, **OPTS), device=ctx, progress=False)
    assert "render" not in again["timing"]["stages_s"]
    assert again["scenes"]["room"]["controls"] == first["scenes"]["room"]["controls"]
    # A lost control cell is recomputed, not silently dropped.
    cells = sorted((out / ".r360cache" / "views").glob("*/room/pre/*.json"))
    assert cells
    cells[0].unlink()
    partial = evaluate(bundle, out=out, options=EvaluateOptions(pictures=False, **OPTS), device=ctx, progress=False)
    assert partial["scenes"]["room"]["controls"] == first["scenes"]["room"]["controls"]


def _rec(iou_pre, empty=False):
    return {"semantic": {"p": {"iou_pre": iou_pre, "empty_target": empty}}}


def _scene(identity=None, reference=None, records=None, axes=("s_sem", "s_geo", "s_str")):
    m_axes = {a: 0.5 for a in axes}
    scene = {"methods": {"m": {"axes": m_axes, "views": records or []}}}
    controls = {}
    if identity is not None:
        controls["identity"] = {"axes": identity, "views": records or []}
    if reference is not None:
        controls["reference"] = {"axes": reference, "views": records or []}
    if controls:
        scene["controls"] = controls
    return scene


def test_detectability_uses_the_best_probe_and_skips_empty_targets():
    recs = [{"semantic": {"a": {"iou_pre": 0.1, "empty_target": False}, "b": {"iou_pre": 0.6, "empty_target": False}}},
            _rec(0.2), _rec(0.0, empty=True)]
    d = detectability(recs, xi=0.3)
    assert d["n_views"] == 2 and d["miou_pre"] == pytest.approx(0.4) and d["detect_frac"] == 0.5
    assert detectability([{"semantic": {}}]) is None


@pytest.mark.parametrize("ident, want", [(0.51, "blind"), (0.5, "weak"), (0.21, "weak"), (0.2, "ok"), (0.0, "ok")])
def test_identity_control_thresholds(ident, want):
    recs = [_rec(0.9)] * 5
    v, notes, _ = scene_validity(_scene(identity={"s_sem": 0.0, "s_geo": ident, "s_str": 0.0}, records=recs))
    assert v["s_geo"] == want and v["s_sem"] == "ok" and v["s_str"] == "ok"
    assert ("s_geo" in notes) == (want != "ok")


def test_reference_control_that_misses_a_real_removal_is_weak():
    recs = [_rec(0.9)] * 5
    v, notes, _ = scene_validity(_scene(identity={"s_sem": 0.0, "s_geo": 0.0, "s_str": 0.0},
                                        reference={"s_sem": 1.0, "s_geo": 0.49, "s_str": 1.0}, records=recs))
    assert v == {"s_sem": "ok", "s_geo": "weak", "s_str": "ok"}
    assert "reference control" in notes["s_geo"]


def test_a_probe_that_never_saw_the_target_is_blind_without_controls():
    recs = [_rec(0.19)] * 4 + [_rec(0.5)]  # found in 1 of 5 views
    v, notes, det = scene_validity(_scene(records=recs))
    assert v["s_sem"] == "blind" and det["detect_frac"] == pytest.approx(0.2)
    assert "20%" in notes["s_sem"]
    recs = [_rec(0.9)] * 3 + [_rec(0.1)] * 2  # found in 60%: weak
    assert scene_validity(_scene(records=recs))[0]["s_sem"] == "weak"
    recs = [_rec(0.4)] * 5  # always found but mIoU_pre 0.4: weak
    assert scene_validity(_scene(records=recs))[0]["s_sem"] == "weak"


def test_axes_not_computed_have_no_verdict_and_not_ok_cells_are_listed():
    v, _, _ = scene_validity(_scene(identity={"s_sem": 0.9}, records=[_rec(0.9)], axes=("s_sem",)))
    assert v == {"s_sem": "blind", "s_geo": None, "s_str": None}
    cells = not_ok_cells({"a": {"validity": v}, "b": {"validity": {"s_sem": "ok", "s_geo": "weak"}}})
    assert cells["s_sem"] == ["a"] and cells["s_geo"] == ["b"] and cells["s_str"] == []


def test_console_summary_marks_axes_that_are_not_ok_somewhere():
    res = {"aggregate": {"overall": {"m": {"s_sem": 0.9, "s_geo": 0.5, "s_str": 0.7, "rqs": 0.6}},
                         "overall_pooling": "view-weighted", "ranks": {"m": {"avg_rank": 1.0}}},
           "validity": {"s_sem": [], "s_geo": [], "s_str": ["garden"]},
           "scenes": {"garden": {"validity": {"s_sem": "ok", "s_geo": "ok", "s_str": "blind"},
                                 "validity_notes": {"s_str": "structural axis blind: because."},
                                 "controls": {"identity": {"axes": {"s_sem": 0.0, "s_geo": 0.0, "s_str": 0.7}}}}}}
    lines = summary_lines(res)
    row = next(line for line in lines if line.strip().startswith("m "))
    assert "0.700!" in row and "0.900 " in row and "0.900!" not in row
    assert any("s_str in garden" in line for line in lines)
    assert any("structural axis blind: because." in line for line in lines)


def test_overall_tables_mark_axes_that_are_not_ok_somewhere(with_controls):
    """tables.md / .tex: the Overall cells of an axis that is weak or blind in some scene carry a dagger."""
    import copy

    from r360gpu.report.results_tables import main_table
    from r360gpu.report.tables import render_latex as to_latex, render_markdown as to_markdown

    _, res = with_controls
    res = copy.deepcopy(res)
    res["validity"] = {"s_sem": [], "s_geo": ["room"], "s_str": []}
    md = to_markdown(main_table(res))
    geo_col = [line.split("|")[4] for line in md.splitlines() if line.startswith("| clean")][0]
    sem_col = [line.split("|")[3] for line in md.splitlines() if line.startswith("| clean")][0]
    assert "\u2020" in geo_col and "\u2020" not in sem_col
    assert "s_geo: the probe check is not ok (weak or blind) in room" in md
    assert r"$^{\dagger}$" in to_latex(main_table(res))
    res["validity"] = {"s_sem": [], "s_geo": [], "s_str": []}
    assert "\u2020" not in to_markdown(main_table(res))
