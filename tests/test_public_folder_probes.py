"""A public Remove360-layout folder's own probe outputs (gsam2/, SAM JSON) are its default probes;
the console and results.json say which probes ran and why; sam-json:ROOT reads the folder's root;
probe-spec errors name the path and show a spec that works."""
from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from bundle_factory import VIEWS, make_remove360, mask_image
from r360gpu.cli import main
from r360gpu.errors import InputError
from r360gpu.probes.precomputed import PrecomputedStructuralProbe
from r360gpu.probes.registry import parse_probe_spec, probe_for_axis

FAST = ["--no-pictures", "--no-boundary", "--n-boot", "200", "--n-perm", "100", "--quiet"]


def _sam(masks: list[np.ndarray]) -> str:
    return json.dumps([{"segmentation": m.astype(bool).tolist(), "area": int(m.sum())} for m in masks])


@pytest.fixture
def folder(tmp_path):
    """make_remove360 plus the public scripts' outputs: GSAM2 masks (before: the target; after: nothing
    found, no PNG written), SAM JSON of images/before in masks/ and of rgb/after in sam/after (the
    same segments: the structure is unchanged)."""
    root = make_remove360(tmp_path / "bedroom_table")
    target = mask_image() > 0
    rest = ~target
    for v in VIEWS:
        (root / "gsam2" / "before" / "mask").mkdir(parents=True, exist_ok=True)
        (root / "gsam2" / "after" / "mask").mkdir(parents=True, exist_ok=True)
        assert cv2.imwrite(str(root / "gsam2" / "before" / "mask" / f"{v}.png"), mask_image())
        (root / "masks" / f"{v}.json").write_text(_sam([target, rest]))
        (root / "sam" / "after").mkdir(parents=True, exist_ok=True)
        (root / "sam" / "after" / f"{v}.json").write_text(_sam([target, rest]))
    return root


def _score(args, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["score", *args, "--out", str(out), *FAST]) == 0
    return json.loads((out / "results.json").read_text()), capsys.readouterr().out


def test_the_folders_outputs_are_the_default_probes(folder, tmp_path, capsys):
    res, console = _score([str(folder)], tmp_path, capsys)
    sel = res["probes"]["selection"]["bedroom_table"]
    assert sel["semantic"]["source"] == "folder" and sel["semantic"]["probes"] == ["gsam2-folder"]
    assert sel["structural"]["source"] == "folder" and sel["structural"]["probes"] == ["sam-folder"]
    assert "gsam2/before/mask" in sel["semantic"]["why"] and "pre=masks" in sel["structural"]["why"]
    assert [p["name"] for p in res["probes"]["semantic"]] == ["gsam2-folder"]
    assert "probes: bedroom_table semantic: gsam2-folder (folder)" in console
    axes = res["scenes"]["bedroom_table"]["methods"]["after"]["axes"]
    # the GSAM2 "before" masks are the target masks: IoU_pre 1; no "after" mask: nothing detected
    assert axes["iou_pre"] == pytest.approx(1.0) and axes["iou_post"] == 0.0 and axes["s_sem"] == 1.0
    # SAM gives the same segments before and after (the RGB renders differ): sim_SAM 1, s_str 0
    assert axes["s_str"] == 0.0


def test_builtin_on_the_command_line_wins_and_folders_without_outputs_say_why(folder, tmp_path, capsys):
    res, _ = _score([str(folder), "--semantic-probe", "builtin"], tmp_path, capsys)
    sel = res["probes"]["selection"]["bedroom_table"]
    assert sel["semantic"] == {"probes": ["builtin-appearance"], "source": "command line", "why": "given by the caller"}
    assert sel["structural"]["source"] == "folder"
    shutil.rmtree(folder / "gsam2")
    shutil.rmtree(folder / "sam")
    res, console = _score([str(folder)], tmp_path / "again", capsys)
    sel = res["probes"]["selection"]["bedroom_table"]
    assert sel["semantic"]["source"] == "default" and "no the folder's GSAM2" not in sel["semantic"]["why"]
    assert "has no the folder's" not in console and "gsam2/before/mask" in sel["semantic"]["why"]
    from r360gpu.probes.registry import DEFAULT_PROBES

    assert sel["structural"]["probes"] == [DEFAULT_PROBES["structural"]] and "sam/after" in sel["structural"]["why"]


def test_compat_keeps_the_built_ins_and_says_so(folder, tmp_path, capsys):
    res, _ = _score([str(folder), "--compat"], tmp_path, capsys)
    sel = res["probes"]["selection"]["bedroom_table"]
    assert sel["semantic"]["source"] == "default" and "--compat" in sel["semantic"]["why"]
    assert [p["name"] for p in res["probes"]["semantic"]] == ["builtin-appearance"]


def test_sam_json_takes_the_folders_root(folder, tmp_path, capsys):
    probe = probe_for_axis(f"sam-json:{folder}", "structural")
    assert isinstance(probe, PrecomputedStructuralProbe)
    assert probe.params()["paths"] == {"pre": str(folder / "masks"), "post": str(folder / "sam" / "after")}
    (folder / "sam" / "before").mkdir()
    (folder / "sam" / "before" / "bedroom_table.json").write_text("[]")
    assert parse_probe_spec(f"sam-json:{folder}").params()["paths"]["pre"] == str(folder / "sam" / "before")
    assert parse_probe_spec(f"png:{folder}").params()["paths"] == {
        "pre": str(folder / "gsam2" / "before" / "mask"), "post": str(folder / "gsam2" / "after" / "mask")}
    (folder / "sam" / "before" / "bedroom_table.json").unlink()
    (folder / "sam" / "before").rmdir()
    res, _ = _score([str(folder), "--structural-probe", f"sam-json:{folder}"], tmp_path, capsys)
    sel = res["probes"]["selection"]["bedroom_table"]["structural"]
    assert sel["source"] == "command line"
    assert res["probes"]["structural"][0]["params"]["paths"] == {"pre": str(folder / "masks"),
                                                                 "post": str(folder / "sam" / "after")}
    assert res["scenes"]["bedroom_table"]["methods"]["after"]["axes"]["s_str"] == 0.0


def test_spec_errors_name_the_path_and_show_a_spec_that_works(folder, tmp_path):
    with pytest.raises(InputError) as e:  # the sam/ folder holds post masks only
        parse_probe_spec(f"sam-json:{folder / 'sam'}")
    msg = str(e.value)
    assert str(folder / "sam" / "after") in msg and f"a spec that works: sam-json:{folder} " in msg
    empty = tmp_path / "elsewhere"
    (empty / "a").mkdir(parents=True)
    (empty / "b").mkdir()
    (empty / "a" / "v.json").write_text("[]")
    (empty / "b" / "v.json").write_text("[]")
    with pytest.raises(InputError) as e:
        parse_probe_spec(f"sam-json:{empty}")
    assert str(empty) in str(e.value) and f"sam-json:pre={empty / 'a'},post={empty / 'b'}" in str(e.value)
    with pytest.raises(InputError, match="does not exist.*pre=DIR,post=DIR") as e:
        parse_probe_spec(f"sam-json:{tmp_path / 'nope'}")
    assert str(tmp_path / "nope") in str(e.value)


def test_cli_spec_error_is_one_line_with_the_path(folder, tmp_path, capsys):
    assert main(["score", str(folder), "--structural-probe", f"sam-json:{folder / 'sam'}",
                 "--out", str(tmp_path / "o"), *FAST]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(folder / "sam") in err and f"sam-json:{folder}" in err
