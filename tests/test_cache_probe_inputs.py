"""The view cache and precomputed probe files: a rerun after any of them changed gives what a fresh
run gives (the cells carry the files' stamps, taken before reading: util.filehash.input_stamp).

Each case scores a public-layout folder with precomputed masks into one --out, changes one probe
input in a way that changes the scores, and scores again into the same --out: the results must be
a fresh run's on a new --out, and must differ from the first run's (so the change mattered).
"""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from bundle_factory import VIEWS, make_remove360, mask_image
from r360gpu.cli import main
from r360gpu.util import filehash

FAST = ["--no-pictures", "--no-boundary", "--n-boot", "200", "--n-perm", "100", "--quiet"]
TARGET = mask_image() > 0
REST = ~TARGET


def _sam(masks) -> str:
    return json.dumps([{"segmentation": np.asarray(m, bool).tolist(), "area": int(np.sum(m))} for m in masks])


def _png(path, mask) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.asarray(mask, np.uint8) * 255)


@pytest.fixture
def settled_at_once(monkeypatch):
    """Files written by the test count as settled at once (the 2 s rule is tested on its own below)."""
    monkeypatch.setattr(filehash, "_SETTLED_NS", -1)


def _folder(root):
    """make_remove360 plus GSAM2 PNG masks (before: the target; after: none) and SAM JSON (pre in
    masks/, post in sam/after: the target and the rest, so the structure looks unchanged)."""
    root = make_remove360(root)
    for v in VIEWS:
        _png(root / "gsam2" / "before" / "mask" / f"{v}.png", TARGET)
        (root / "gsam2" / "after" / "mask").mkdir(parents=True, exist_ok=True)
        (root / "masks" / f"{v}.json").write_text(_sam([TARGET, REST]))
        (root / "sam" / "after").mkdir(parents=True, exist_ok=True)
        (root / "sam" / "after" / f"{v}.json").write_text(_sam([TARGET, REST]))
    return root


def _amg_folder(root, view, masks) -> None:
    """segment-anything scripts/amg.py output for one view: metadata.csv and one PNG per mask."""
    folder = root / view
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["id,area,bbox_x0,bbox_y0,bbox_w,bbox_h,point_input_x,point_input_y,predicted_iou,"
             "stability_score,crop_box_x0,crop_box_y0,crop_box_w,crop_box_h"]
    for i, m in enumerate(masks):
        _png(folder / f"{i}.png", m)
        lines.append(f"{i},{int(m.sum())},0,0,1,1,0,0,0.9,0.9,0,0,{m.shape[1]},{m.shape[0]}")
    (folder / "metadata.csv").write_text("\n".join(lines) + "\n")


def _gsam2_dump(path, view, mask) -> None:
    """A Grounded-SAM-2 JSON dump with one instance (uncompressed RLE would do; a polygon-free box +
    mask as the public converter reads it)."""
    from r360gpu.probes import rle

    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    ann = {"class_name": "table", "bbox": [int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())],
           "segmentation": rle.encode(mask), "score": [0.9]}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"image_path": f"/x/{view}.png", "annotations": [ann], "box_format": "xyxy",
                                "img_width": w, "img_height": h}))


def _changes(root):
    """(probe flags, how to change one input) per kind of precomputed probe file."""
    half = TARGET.copy()
    half[:, : half.shape[1] // 2] = False
    return {
        "sam-json post file": ([], lambda: (root / "sam" / "after" / f"{VIEWS[1]}.json").write_text(_sam([REST]))),
        "sam-json pre file": ([], lambda: (root / "masks" / f"{VIEWS[2]}.json").write_text(_sam([REST]))),
        "sam-json merged.json appears": (
            [], lambda: (root / "sam" / "after" / "merged.json").write_text(
                json.dumps({f"{v}.png": json.loads(_sam([REST])) for v in VIEWS}))),
        "png mask appears": ([], lambda: _png(root / "gsam2" / "after" / "mask" / f"{VIEWS[0]}.png", TARGET)),
        "png mask changed": ([], lambda: _png(root / "gsam2" / "before" / "mask" / f"{VIEWS[1]}.png", half)),
        "amg folder mask changed": (
            ["--structural-probe", f"sam-json:pre={root / 'amg' / 'pre'},post={root / 'amg' / 'post'}"],
            lambda: _png(root / "amg" / "post" / VIEWS[1] / "0.png", REST)),
        "gsam2-json dump changed": (
            ["--semantic-probe", f"gsam2-json:pre={root / 'dumps' / 'pre'},post={root / 'dumps' / 'post'}"],
            lambda: _gsam2_dump(root / "dumps" / "post" / "d1.json", VIEWS[1], TARGET)),
    }


def _axes(out) -> dict:
    doc = json.loads((out / "results.json").read_text())
    (scene,) = doc["scenes"].values()
    return {k: v for k, v in scene["methods"]["after"]["axes"].items() if k.startswith(("s_", "iou", "sim"))}


@pytest.mark.parametrize("case", ["sam-json post file", "sam-json pre file", "sam-json merged.json appears",
                                  "png mask appears", "png mask changed", "amg folder mask changed",
                                  "gsam2-json dump changed"])
def test_a_changed_probe_file_is_read_again(case, settled_at_once, tmp_path, capsys):
    root = _folder(tmp_path / "scene")
    for r in ("pre", "post"):
        for v in VIEWS:
            _amg_folder(root / "amg" / r, v, [TARGET, REST])
    for v in VIEWS:
        _gsam2_dump(root / "dumps" / "pre" / f"d{VIEWS.index(v)}.json", v, TARGET)
    _gsam2_dump(root / "dumps" / "post" / "d1.json", VIEWS[1], REST)
    flags, change = _changes(root)[case]
    out = tmp_path / "out"
    args = ["score", str(root), "--out", str(out), *flags, *FAST]
    assert main(args) == 0, capsys.readouterr().err
    first = _axes(out)
    assert main(args) == 0  # everything from the cache
    assert json.loads((out / "results.json").read_text())["timing"]["stages_s"].get("probe", 0) == 0
    change()
    assert main(args) == 0, capsys.readouterr().err
    fresh = tmp_path / "fresh"
    assert main(["score", str(root), "--out", str(fresh), *flags, *FAST]) == 0
    assert _axes(out) == _axes(fresh)
    assert _axes(fresh) != first, "the change did not change the scores: the case checks nothing"


def test_a_probe_file_written_within_2_s_keeps_its_view_out_of_the_cache(tmp_path, capsys):
    """Two writes in one tick of the file system's clock can leave the same stamp: a view read from
    a file written less than 2 s before is scored again by the next run (no warning: nothing is wrong)."""
    root = _folder(tmp_path / "scene")
    out = tmp_path / "out"
    args = ["score", str(root), "--out", str(out), *FAST]
    assert main(args) == 0
    assert main(args) == 0
    doc = json.loads((out / "results.json").read_text())
    assert doc["timing"]["stages_s"].get("probe", 0) > 0  # scored again: nothing was cached
    assert "changed while the run read it" not in capsys.readouterr().err


def test_a_probe_file_changed_while_the_run_reads_it_is_not_cached(settled_at_once, tmp_path, monkeypatch, capsys):
    """The file's stamp after the view is scored is not the one taken before it was read: the view's
    cells are not stored, with a warning naming the file; the next run scores it again."""
    root = _folder(tmp_path / "scene")
    target = root / "sam" / "after" / f"{VIEWS[1]}.json"
    from r360gpu.probes import sam_records

    real = sam_records.read_sam_json

    def read_then_touch(path, probe=""):
        got = real(path, probe)
        if str(path) == str(target):
            target.write_text(target.read_text())  # same bytes, new ctime: "changed" as far as a stamp knows
        return got

    monkeypatch.setattr(sam_records, "read_sam_json", read_then_touch)
    out = tmp_path / "out"
    assert main(["score", str(root), "--out", str(out), *FAST]) == 0
    err = capsys.readouterr().err
    assert "changed while the run read it" in err and f"{VIEWS[1]}.json" in err
    monkeypatch.setattr(sam_records, "read_sam_json", real)
    assert main(["score", str(root), "--out", str(out), *FAST]) == 0
    doc = json.loads((out / "results.json").read_text())
    assert doc["timing"]["stages_s"].get("probe", 0) > 0  # view_01 scored again
