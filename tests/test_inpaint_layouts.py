"""The ``inpaint`` command end to end on generated 360-USID and SPIn-NeRF folders: every value equal to the
numpy model of the script (tests/aura_eval_oracle.py) to 1e-4; hostile folders refused with exit 2, naming
the file, writing nothing."""
from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from PIL import Image

from r360gpu.cli import main
from r360gpu.metrics.json_values import dec_tree
from r360gpu.synthetic.inpaint_folders import write_inpaint_example
from tests import aura_eval_oracle as oracle

TOL = 1e-4
OUTPUTS = ("results.json", "results.csv", "tables.md", "tables.tex", "report.html")


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    root = tmp_path_factory.mktemp("inpaint") / "example"
    write_inpaint_example(root, n_scenes=2, n_views=3, width=40, height=32, seed=1, n_train=2)
    return root


@pytest.fixture
def folder(example, tmp_path):
    """A private copy to damage."""
    dst = tmp_path / "ex"
    shutil.copytree(example, dst)
    return dst


def _usid_args(root, out, *extra):
    u = root / "360usid"
    return ["inpaint", "360usid", str(u / "data"), f"blur={u}/output/{{scene}}/test/blur",
            f"flat={u}/output/{{scene}}/test/flat", "--masks", f"{u}/output/{{scene}}/test/ours_30000/object_mask",
            "--out", str(out), "--quiet", *extra]


def _doc(out):
    return dec_tree(json.loads((out / "results.json").read_text()))


def _close(a, b):
    if math.isnan(b) or math.isinf(b):
        assert a == b or (math.isnan(a) and math.isnan(b))
    else:
        assert abs(a - b) <= TOL, (a, b)


def test_360usid_compat_equals_the_script(example, tmp_path):
    out = tmp_path / "out"
    assert main(_usid_args(example, out, "--compat")) == 0
    doc = _doc(out)
    assert doc["schema"] == "r360gpu.inpaint/1" and doc["mode"] == "compat" and doc["differs_from_script"] == []
    u = example / "360usid"
    for scene in ("carton", "cone"):
        for method in ("blur", "flat"):
            ref = oracle.score_usid_scene(u / "data" / scene, u / "output" / scene / "test" / method,
                                          u / "output" / scene / "test" / "ours_30000" / "object_mask")
            got = doc["scenes"][scene][method]["means"]
            for k, v in ref.items():
                _close(got[k]["mean"], v)
    assert all((out / f).is_file() for f in OUTPUTS)
    assert "PSNR$_{\\mathrm{obj}}" in (out / "tables.tex").read_text()
    rows = (out / "results.csv").read_text().splitlines()
    assert rows[0].startswith("scene,method,view,psnr") and len(rows) == 1 + 2 * 2 * 3


def test_360usid_default_mode_binary_masks(example, tmp_path):
    out = tmp_path / "out"
    assert main(_usid_args(example, out)) == 0
    doc = _doc(out)
    assert doc["mode"] == "default" and doc["differs_from_script"]
    u = example / "360usid"
    gts = oracle.natsorted_paths((u / "data" / "carton" / "test_images").glob("*jpg"))
    masks = oracle.natsorted_paths((u / "output" / "carton" / "test" / "ours_30000" / "object_mask").glob("*.png"))
    renders = oracle.natsorted_paths((u / "output" / "carton" / "test" / "blur" / "renders").glob("*png"))
    views = doc["scenes"]["carton"]["blur"]["views"]
    for v, g, r, m in zip(views, gts, renders, masks):
        gt, img = oracle.read_rgb(g), oracle.read_rgb(r)
        binary = (oracle.read_mask(m) != 0).astype(np.float32)  # default: any non-zero pixel, weight 1
        assert v["view"] == g.name
        _close(v["psnr"], oracle.psnr(img, gt))
        _close(v["masked_psnr"], oracle.masked_psnr(img, gt, binary))
        _close(v["masked_ssim"], oracle.masked_ssim(img, gt, binary))
    # the anti-aliased edges make the script's fractional weights differ from the binary mask
    compat = tmp_path / "compat"
    main(_usid_args(example, compat, "--compat"))
    assert _doc(compat)["scenes"]["carton"]["blur"]["views"][0]["masked_ssim"] != views[0]["masked_ssim"]


def test_spinnerf_layout(example, tmp_path):
    out = tmp_path / "out"
    s = example / "spinnerf"
    rc = main(["inpaint", "spinnerf", str(s / "data"), f"blur={s}/output/{{scene}}/blur", "--n-test", "3",
               "--out", str(out), "--quiet", "--compat"])
    assert rc == 0
    doc = _doc(out)
    photos = oracle.natsorted_paths((s / "data" / "carton" / "images").glob("*.jpg"))[:3]
    renders = oracle.natsorted_paths((s / "output" / "carton" / "blur" / "renders").glob("*.png"))
    masks = [s / "data" / "carton" / "images" / "label" / (p.stem + ".png") for p in photos]
    ref = oracle.score_pair_lists(photos, renders, masks)
    views = doc["scenes"]["carton"]["blur"]["views"]
    assert [v["view"] for v in views] == [p.name for p in photos]
    for k, vals in ref.items():
        for v, r in zip(views, vals):
            _close(v[k], r)


def _fails(capsys, args, *needles):
    assert main(args) == 2
    err = capsys.readouterr().err
    for n in needles:
        assert str(n) in err, err
    return err


def test_count_mismatch_names_the_folder_writes_nothing(folder, tmp_path, capsys):
    renders = folder / "360usid/output/cone/test/flat/renders"
    (renders / "00002.png").unlink()
    out = tmp_path / "out"
    _fails(capsys, _usid_args(folder, out), renders, "2 renders")
    assert not out.exists()


def test_size_mismatch_and_unreadable_image(folder, tmp_path, capsys):
    out = tmp_path / "out"
    bad = folder / "360usid/output/carton/test/blur/renders/00001.png"
    Image.new("RGB", (41, 32)).save(bad)
    _fails(capsys, _usid_args(folder, out), bad, "41x32")
    bad.write_bytes(b"not a png")
    _fails(capsys, _usid_args(folder, out), bad, "cannot read")
    assert not out.exists()


def test_missing_folders(folder, tmp_path, capsys):
    out = tmp_path / "out"
    _fails(capsys, ["inpaint", "360usid", str(folder / "nope"), "m=x", "--out", str(out)], folder / "nope")
    _fails(capsys, ["inpaint", "360usid", str(folder / "360usid/data"), f"m={folder}/none/{{scene}}", "--out",
                    str(out)], "none")
    _fails(capsys, ["inpaint", "360usid", str(folder / "360usid/data"), "noequals", "--out", str(out)], "NAME=FOLDER")
    assert not out.exists()


def test_compat_refuses_an_rgb_mask_earlier_results_kept(folder, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(_usid_args(folder, out)) == 0
    before = (out / "results.json").read_bytes()
    mask = folder / "360usid/output/cone/test/ours_30000/object_mask/00001.png"
    Image.open(mask).convert("RGB").save(mask)
    _fails(capsys, _usid_args(folder, out, "--compat"), mask, "3 channels")
    assert (out / "results.json").read_bytes() == before
    assert main(_usid_args(folder, out)) == 0  # default mode reads it: any non-zero pixel


def test_empty_mask_default_null_with_warning_compat_nan(folder, tmp_path, capsys):
    mask = folder / "360usid/output/carton/test/ours_30000/object_mask/00000.png"
    Image.new("L", (40, 32)).save(mask)
    out = tmp_path / "out"
    assert main(_usid_args(folder, out)) == 0
    doc = _doc(out)
    v = doc["scenes"]["carton"]["blur"]["views"][0]
    assert v["masked_psnr"] is None and "empty" in v["reasons"]["masked_psnr"]
    assert doc["scenes"]["carton"]["blur"]["means"]["masked_psnr"]["n_missing"] == 1
    assert any("empty object mask" in w["message"] for w in doc["warnings"])
    assert main(_usid_args(folder, tmp_path / "c", "--compat")) == 0
    c = _doc(tmp_path / "c")["scenes"]["carton"]["blur"]
    assert math.isnan(c["views"][0]["masked_psnr"]) and c["views"][0]["masked_ssim"] == 1.0
    assert math.isnan(c["means"]["masked_psnr"]["mean"])  # np.mean with a NaN, as the script prints it


def test_example_refuses_a_foreign_folder(tmp_path, capsys):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "keep.txt").write_text("x")
    _fails(capsys, ["inpaint", "example", str(tmp_path / "mine")], "not an example folder")
    assert (tmp_path / "mine" / "keep.txt").exists()


def test_spinnerf_01_labels_warned_in_compat(example, tmp_path):
    """SPIn-NeRF's labels are 0/1: the script's to_tensor makes them 1/255 weights; default mode reads them whole."""
    s = example / "spinnerf"
    args = ["inpaint", "spinnerf", str(s / "data"), f"blur={s}/output/{{scene}}/blur", "--n-test", "3", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "c"), "--compat"]) == 0
    assert main([*args, "--out", str(tmp_path / "d")]) == 0
    c, d = _doc(tmp_path / "c"), _doc(tmp_path / "d")
    assert any("at most 0.003922" in w["message"] for w in c["warnings"])
    cv, dv = c["scenes"]["carton"]["blur"]["views"][0], d["scenes"]["carton"]["blur"]["views"][0]
    assert cv["masked_psnr"] == dv["masked_psnr"]  # the same pixels: any non-zero value
    assert cv["masked_ssim"] > dv["masked_ssim"]  # weighted by 1/255 the object nearly vanishes
