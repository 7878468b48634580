"""`r360gpu score --compat` on a public-layout folder against the public Remove360 modules' own numbers.

tests/data/compat_public/expected.json was written by running the public evaluation
modules (simonakocour/anything_left, unchanged) on tests/data/compat_public/office_chair;
tests/data/compat_public/README.md says how.  Neither torch nor the public code is needed here.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import r360gpu.cli as cli
from r360gpu.errors import InputError
from r360gpu.metrics.compat import depth_delta, public_changed, read_depth_public
from r360gpu.metrics.compat_public import evaluate_public_folder, resize_torch_nearest
from r360gpu.pipeline import EvaluateOptions

DATA = Path(__file__).parent / "data" / "compat_public"
SCENE = DATA / "office_chair"
EXPECTED = json.loads((DATA / "expected.json").read_text())
MODES = ("public", "public-default")


def expected_views(mode: str) -> dict:
    """{axis: {view: value}} as the public modules returned them."""
    return {
        "semantic": {e["image_name"][: -len(".png")]: (e["iou_before"], e["iou_after"], e["iou_drop"])
                     for e in EXPECTED["semantic"]["views"]},
        "geometric": {e["image"]: e["acc_delta_depth"] for e in EXPECTED["depth"][mode]["views"]},
        "structural": {k: v["sim_sam"] for k, v in EXPECTED["sam"]["views"].items()},
    }


def expected_scene(mode: str) -> dict:
    s = EXPECTED["semantic"]["summary"]
    return {"s_sem": s["acc_seg_30"], "acc_seg_0.5": s["acc_seg_50"], "iou_pre": s["mean_iou_before"],
            "iou_post": s["mean_iou_after"], "iou_drop": s["mean_iou_drop"],
            "s_geo": EXPECTED["depth"][mode]["summary"]["mean_acc_delta_depth"],
            "s_str": EXPECTED["sam"]["mean_sim_sam"]}


def ours_views(res: dict) -> dict:
    v = res["views"]
    return {
        "semantic": {k: (d["iou_pre"], d["iou_post"], d["iou_drop"]) for k, d in v["semantic"].items()},
        "geometric": {k: d["acc_depth"] for k, d in v["geometric"].items()},
        "structural": {k: d["sim_sam"] for k, d in v["structural"].items() if d["reported"]},
    }


def parity(ours: dict, theirs: dict) -> dict:
    """{axis: (values reproduced exactly, values compared)}; the view sets must be equal."""
    out = {}
    for axis in theirs:
        assert set(ours[axis]) == set(theirs[axis]), axis
        out[axis] = (sum(ours[axis][k] == theirs[axis][k] for k in theirs[axis]), len(theirs[axis]))
    return out


@pytest.mark.parametrize("mode", MODES)
def test_folder_values_equal_the_public_modules(mode):
    res = evaluate_public_folder(SCENE, mode)
    counts = parity(ours_views(res), expected_views(mode))
    assert all(n == m and m > 0 for n, m in counts.values()), counts
    sc = res["scene"]
    exp = expected_scene(mode)
    got = {"s_sem": sc["s_sem"], "acc_seg_0.5": sc["acc_seg"]["0.5"], "iou_pre": sc["iou_pre"],
           "iou_post": sc["iou_post"], "iou_drop": sc["iou_drop"], "s_geo": sc["s_geo"], "s_str": sc["s_str"]}
    assert got == exp
    # The public SAM script skips views where either side keeps no mask (v01, v03) and views
    # without SAM output (v05); the depth script scores v06, which has no target mask, as 0.
    assert sc["n_views"] == {"semantic": 6, "geometric": 7, "structural": 3, "structural_not_reported": 2}


@pytest.mark.parametrize("mode", MODES)
def test_score_cli_reports_the_public_numbers(mode, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["score", str(SCENE), "--compat" if mode == "public" else f"--compat={mode}", "--out", str(out),
            "--no-pictures", "--no-boundary", "--n-boot", "50", "--n-perm", "50", "--quiet"]
    assert cli.main(argv) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["options"]["compat"] == mode
    cell = results["scenes"]["office_chair"]["methods"]["after"]
    axes = cell["axes"]
    exp = expected_scene(mode)
    assert axes["s_sem"] == exp["s_sem"] and axes["acc_seg"]["0.5"] == exp["acc_seg_0.5"]
    assert (axes["iou_pre"], axes["iou_post"], axes["iou_drop"]) == (exp["iou_pre"], exp["iou_post"], exp["iou_drop"])
    assert axes["s_geo"] == exp["s_geo"] and axes["s_str"] == exp["s_str"] and axes["sim_sam"] == exp["s_str"]
    assert axes["rqs"] == pytest.approx((exp["s_sem"] * exp["s_geo"] * exp["s_str"]) ** (1 / 3), rel=1e-12)
    assert axes["compat"]["mode"] == mode
    # Per-view records carry the public per-view values (the records are the bundle's views: v00..v05).
    theirs = expected_views(mode)
    records = {r["view"]: r["compat"] for r in cell["views"]}
    assert sorted(records) == [f"v0{i}" for i in range(6)]
    for v, rec in records.items():
        s = rec["semantic"]
        assert (s["iou_pre"], s["iou_post"], s["iou_drop"]) == theirs["semantic"][v]
        assert rec["geometric"]["acc_depth"] == theirs["geometric"][v]
        st = rec["structural"]
        if v in theirs["structural"]:
            assert st["reported"] and st["sim_sam"] == theirs["structural"][v]
        else:
            assert st is None or not st["reported"]
    printed = capsys.readouterr().out
    assert f"{exp['s_geo']:.3f}" in printed


def test_the_fixture_sees_the_uint8_wrap():
    # With r360gpu's own rule (both kinds of hole zeroed) v00 would read 0.9125, not the scripts' 0.05.
    pre = read_depth_public(SCENE / "depth" / "before" / "v00.png")
    post = read_depth_public(SCENE / "depth" / "after" / "v00.png")
    target = np.asarray(read_depth_public(SCENE / "masks" / "v00.png")) > 0
    wrong = public_changed(depth_delta(pre, post), "public").changed
    assert (wrong & target).sum() / target.sum() != expected_views("public")["geometric"]["v00"]


def test_nearest_resizes():
    a = np.arange(12).reshape(3, 4)
    np.testing.assert_array_equal(resize_torch_nearest(a, (6, 8)), np.repeat(np.repeat(a, 2, 0), 2, 1))
    assert resize_torch_nearest(a, (3, 4)) is a
    np.testing.assert_array_equal(resize_torch_nearest(a, (2, 2)), a[[0, 1]][:, [0, 2]])
    np.testing.assert_array_equal(resize_torch_nearest(a, (2, 2), exact=True), a[[0, 2]][:, [1, 3]])


def test_options_accept_true_as_public_and_reject_unknown_modes(capsys):
    assert EvaluateOptions(compat=True).compat == "public"
    assert EvaluateOptions().compat is None
    with pytest.raises(InputError):
        EvaluateOptions(compat="8bit")
    with pytest.raises(SystemExit):
        cli.main(["score", "--compat", str(SCENE), "--out", "x"])
    assert "--compat=public" in capsys.readouterr().err


def test_missing_masks_folder_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="masks"):
        evaluate_public_folder(tmp_path, "public")


def test_compat_axes_are_made_once_from_the_own_axes():
    """The scene's compat axes are built beside r360gpu's own (kept under compat.replaced, the
    own dict left as it was); a bundle of another layout keeps its axes and gets the note."""
    from dataclasses import replace

    from r360gpu.aggregate.compat import NOT_PUBLIC_NOTE, scene_compat
    from r360gpu.bundle import load_bundle

    bundle = load_bundle(SCENE)
    own = {"s_sem": 0.5, "acc_seg": {"0.3": 0.5}, "s_geo": None, "s_str": 0.25, "rqs": None, "n_views": 4,
           "n_no_depth": 4, "n_geo_excluded": 0}
    before = json.dumps(own)
    sc = scene_compat(bundle, list(bundle.methods), "public")
    axes = sc.axes(own)
    assert json.dumps(own) == before  # not patched
    exp = expected_scene("public")
    assert axes["s_geo"] == exp["s_geo"] and axes["s_str"] == exp["s_str"] and axes["n_no_depth"] == 0
    assert axes["compat"]["replaced"]["s_geo"] is None and axes["compat"]["replaced"]["s_sem"] == 0.5
    rec = sc.view({"view": "v00", "semantic": {}})
    assert rec["compat"]["geometric"]["acc_depth"] == expected_views("public")["geometric"]["v00"]
    other = scene_compat(replace(bundle, layout="scene.toml"), list(bundle.methods), "public-default")
    assert other.axes(own) is own and other.notes == [NOT_PUBLIC_NOTE.format(mode="public-default")]
    assert other.view({"view": "v00"}) == {"view": "v00"}
    assert scene_compat(bundle, list(bundle.methods), None) is None
    with pytest.raises(ValueError, match="one method"):
        scene_compat(bundle, ["a", "b"], "public")


def test_validity_weighs_the_own_axes_in_compat_mode(tmp_path):
    """In compat mode the pipeline reads no depth of a public folder: the geometric verdict is None
    (r360gpu computed no s_geo) although the method's s_geo is the public scripts'."""
    out = tmp_path / "out"
    assert cli.main(["score", str(SCENE), "--compat", "--out", str(out), "--no-pictures", "--no-boundary",
                     "--n-boot", "50", "--n-perm", "50", "--quiet"]) == 0
    scene = json.loads((out / "results.json").read_text())["scenes"]["office_chair"]
    assert scene["methods"]["after"]["axes"]["s_geo"] == expected_scene("public")["s_geo"]
    assert scene["validity"]["s_geo"] is None and scene["validity"]["s_sem"] == "ok"
    assert scene["notes"] == []
