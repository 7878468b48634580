"""The ``inpaint`` command's model metrics (LPIPS, masked LPIPS, FID, KID) end to end on the generated
folders, with the tiny stand-in exports of tests/test_lpips_spatial.py and tests/test_probes_inception.py.

LPIPS and masked LPIPS are checked against the script's arithmetic written out here on the images
read as the script reads them (tests/aura_eval_oracle.py): ``lpips(render, gt)`` without
``normalize`` in compat mode, ``sum(map * mask) / sum(mask)`` with the script's mask weights.  FID
and KID are checked for the image sets and features they are given (the library's
`InceptionModel.features` of the files pytorch-fid reads); FID's own value is tested in
tests/test_fid.py (a 2048-dimensional FID takes tens of seconds, so the command's call is recorded
here instead of repeated).
"""
from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest
from PIL import Image

onnx = pytest.importorskip("onnx")

from r360gpu.cli import main  # noqa: E402
from r360gpu.metrics.fid import Fid, fid_image_files, kid_from_features  # noqa: E402
from r360gpu.metrics.inpainting import (EMPTY_MASK, NO_INCEPTION, NO_LPIPS, NO_LPIPS_SPATIAL,  # noqa: E402
                                        score_views)
from r360gpu.metrics.fidelity import LpipsModel  # noqa: E402
from r360gpu.metrics.json_values import dec_tree  # noqa: E402
from r360gpu.pipeline import inpaint as pipeline  # noqa: E402
from r360gpu.probes.inception import InceptionModel  # noqa: E402
from r360gpu.synthetic.inpaint_folders import write_inpaint_example  # noqa: E402
from tests import aura_eval_oracle as oracle  # noqa: E402
from tests.test_lpips_spatial import lpips_like  # noqa: E402
from tests.test_probes_inception import inception_like  # noqa: E402

TOL = 1e-5  # the stand-ins run in float32
SCENES, METHODS = ("carton", "cone"), ("blur", "flat")


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    root = tmp_path_factory.mktemp("inpaint_models") / "example"
    write_inpaint_example(root, n_scenes=2, n_views=3, width=40, height=32, seed=1, n_train=2)
    return root


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("exports")
    return {"plain": lpips_like(d / "lpips_vgg.onnx", spatial=False),
            "spatial": lpips_like(d / "lpips_vgg_spatial.onnx", spatial=True),
            "open": lpips_like(d / "lpips_open.onnx", spatial=True, out_shape=["N", 1, "h", "w"]),
            "inception": inception_like(d / "pt_inception.onnx")}


@pytest.fixture
def fid_calls(monkeypatch):
    """Record the features each FID is given; return a distinct stand-in value per call."""
    calls = []

    def fake(ref, out, *, what=None, **_):
        calls.append((np.array(ref), np.array(out), what))
        return Fid(100.0 + len(calls), None, False, len(ref), len(out))

    monkeypatch.setattr(pipeline, "fid_from_features", fake)
    return calls


def _usid(root, out, *extra):
    u = root / "360usid"
    return ["inpaint", "360usid", str(u / "data"), *(f"{m}={u}/output/{{scene}}/test/{m}" for m in METHODS),
            "--masks", f"{u}/output/{{scene}}/test/ours_30000/object_mask", "--out", str(out), "--quiet", *extra]


def _with_models(models, *keys):
    flags = {"plain": "--lpips-model", "spatial": "--lpips-spatial-model", "inception": "--inception-model"}
    return [a for k in keys for a in (flags[k], str(models[k]))] + ["--probe-device", "cpu"]


def _doc(out):
    return dec_tree(json.loads((out / "results.json").read_text()))


def _files(root, scene, method):
    u = root / "360usid"
    photos = oracle.natsorted_paths((u / "data" / scene / "test_images").glob("*jpg"))
    renders = oracle.natsorted_paths((u / "output" / scene / "test" / method / "renders").glob("*png"))
    masks = oracle.natsorted_paths((u / "output" / scene / "test" / "ours_30000" / "object_mask").glob("*.png"))
    return photos, renders, masks


def _stand_in_map(render, photo, normalize):
    """The stand-ins' LPIPS map mean_c(in0^2 - in1) of (C, H, W) images, in0 the render."""
    if normalize:
        render, photo = 2 * render - 1, 2 * photo - 1
    return np.mean(render.astype(np.float64) ** 2 - photo, axis=0)


def _u8(path):
    return np.array(Image.open(path).convert("RGB"))


def test_compat_lpips_masked_lpips_fid_kid_as_the_script(example, models, fid_calls, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(_usid(example, out, "--compat", *_with_models(models, "plain", "spatial", "inception"))) == 0
    doc = _doc(out)
    inception = InceptionModel(models["inception"])
    for scene in SCENES:
        ref = inception.features(_u8(p) for p in fid_image_files(example / "360usid/data" / scene / "test_images"))
        for method in METHODS:
            got = doc["scenes"][scene][method]
            lp, mlp = [], []
            for p, r, m in zip(*_files(example, scene, method)):
                lmap = _stand_in_map(oracle.read_rgb(r), oracle.read_rgb(p), normalize=False)
                w = oracle.read_mask(m)  # (C, H, W), the script's weights
                lp.append(float(lmap.mean()))
                mlp.append(float(np.sum(lmap[None] * w) / np.sum(w)) if w.sum() else math.nan)
            for v, a, b in zip(got["views"], lp, mlp):
                assert abs(v["lpips"] - a) <= TOL and abs(v["masked_lpips"] - b) <= TOL
            assert abs(got["means"]["lpips"]["mean"] - np.mean(lp)) <= TOL
            assert abs(got["means"]["masked_lpips"]["mean"] - np.mean(mlp)) <= TOL
            # FID and KID over every image of the two folders, as calculate_fid_given_paths.
            i, call = next((i, c) for i, c in enumerate(fid_calls) if c[2] == f"scene {scene}, method {method}")
            renders_dir = example / "360usid/output" / scene / "test" / method / "renders"
            outf = inception.features(_u8(p) for p in fid_image_files(renders_dir))
            np.testing.assert_array_equal(call[0], ref)
            np.testing.assert_array_equal(call[1], outf)
            assert got["fid"] == 101.0 + i and got["set_reason"] is None
            kid = kid_from_features(ref, outf)
            assert got["kid_mean"] == pytest.approx(kid.mean, abs=1e-12) and got["kid_std"] == pytest.approx(kid.std)
            assert (got["n_ref"], got["n_out"]) == (len(ref), len(outf))
    assert len(fid_calls) == len(SCENES) * len(METHODS)
    want = {"lpips_model": models["plain"], "lpips_spatial_model": models["spatial"],
            "inception_model": models["inception"]}
    for key, path in want.items():
        d = doc["inputs"]["models"][key]
        assert d["file"] == path.name and d["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    printed = capsys.readouterr().out
    assert "LPIPS: " in printed and ", FID: 10" in printed and "LPIPS OBJECT: " in printed
    md = (out / "tables.md").read_text()
    assert "| masked LPIPS |" in md and "| FID |" in md and "not computed" not in md
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert header[-3:] == ["fid", "kid_mean", "kid_std"] and "masked_lpips" in header


def test_default_mode_normalizes_and_uses_binary_masks(example, models, tmp_path):
    out = tmp_path / "out"
    assert main(_usid(example, out, *_with_models(models, "plain", "spatial"))) == 0
    doc = _doc(out)
    assert any("LPIPS" in d and "normalize=True" in d for d in doc["differs_from_script"])
    for scene in SCENES:
        got = doc["scenes"][scene]["blur"]
        for v, (p, r, m) in zip(got["views"], zip(*_files(example, scene, "blur"))):
            lmap = _stand_in_map(oracle.read_rgb(r), oracle.read_rgb(p), normalize=True)
            inside = np.asarray(Image.open(m)) != 0
            inside = inside.any(axis=2) if inside.ndim == 3 else inside
            assert abs(v["lpips"] - lmap.mean()) <= TOL
            if inside.any():
                assert abs(v["masked_lpips"] - lmap[inside].mean()) <= TOL
            else:
                assert v["masked_lpips"] is None and v["reasons"]["masked_lpips"] == EMPTY_MASK
        assert got["fid"] is None and got["set_reason"] == NO_INCEPTION


def test_without_models_not_computed_with_the_reason(example, tmp_path):
    out = tmp_path / "out"
    assert main(_usid(example, out)) == 0
    doc = _doc(out)
    got = doc["scenes"]["carton"]["blur"]
    assert all(v["lpips"] is None and v["masked_lpips"] is None for v in got["views"])
    assert got["views"][0]["reasons"]["lpips"] == NO_LPIPS
    assert got["views"][0]["reasons"]["masked_lpips"] == NO_LPIPS_SPATIAL
    assert got["means"]["lpips"]["mean"] is None and got["means"]["lpips"]["reason"] == NO_LPIPS
    assert got["fid"] is None and got["kid_mean"] is None and got["set_reason"] == NO_INCEPTION
    assert doc["inputs"]["models"] == {} and doc["overall"]["blur"]["fid"] is None
    md = (out / "tables.md").read_text()
    assert f"LPIPS: not computed ({NO_LPIPS})" in md and f"FID: not computed ({NO_INCEPTION})" in md
    row = (out / "results.csv").read_text().splitlines()[1].split(",")
    assert row[-3:] == ["", "", ""]


def test_spinnerf_fid_is_over_the_scored_test_views(example, models, fid_calls, tmp_path):
    s = example / "spinnerf"
    out = tmp_path / "out"
    assert main(["inpaint", "spinnerf", str(s / "data"), f"blur={s}/output/{{scene}}/blur", "--n-test", "3",
                 "--out", str(out), "--quiet", *_with_models(models, "inception")]) == 0
    inception = InceptionModel(models["inception"])
    photos = oracle.natsorted_paths((s / "data" / "carton" / "images").glob("*.jpg"))
    assert len(photos) > 3  # the training photographs, with the object, are left out
    ref, outf, what = fid_calls[0]
    assert what == "scene carton, method blur"
    np.testing.assert_array_equal(ref, inception.features(_u8(p) for p in photos[:3]))
    renders = oracle.natsorted_paths((s / "output" / "carton" / "blur" / "renders").glob("*.png"))
    np.testing.assert_array_equal(outf, inception.features(_u8(p) for p in renders))


@pytest.mark.parametrize("flag, key, needle", [
    ("--lpips-model", "spatial", "spatial LPIPS export"),
    ("--lpips-model", "open", "spatial LPIPS export"),
    ("--lpips-spatial-model", "plain", "not a map"),
    ("--inception-model", "plain", "not a pytorch-fid Inception export"),
    ("--lpips-spatial-model", "inception", "two image inputs"),
])
def test_wrong_kind_of_export_exit_2_naming_it_nothing_written(example, models, tmp_path, capsys, flag, key,
                                                               needle):
    out = tmp_path / "out"
    assert main(_usid(example, out, flag, str(models[key]))) == 2
    err = capsys.readouterr().err
    assert models[key].name in err and needle in err, err
    assert not out.exists()


def test_empty_mask_masked_lpips_nan_in_compat_none_in_default(models):
    rng = np.random.default_rng(3)
    photo, render = rng.random((8, 9, 3)), rng.random((8, 9, 3))
    spatial = LpipsModel(models["spatial"])
    empty = np.zeros((8, 9))
    compat = score_views("v", photo, [render], [empty], mode="compat", lpips_spatial=spatial)[0]
    assert math.isnan(compat.masked_lpips)
    default = score_views("v", photo, [render], [empty], mode="default", lpips_spatial=spatial)[0]
    assert default.masked_lpips is None and default.reasons["masked_lpips"] == EMPTY_MASK
    # Fractional script weights weigh the map (compat); masked_lpips keeps them as the script does.
    w = np.zeros((8, 9))
    w[2:5, 3:7] = 0.25
    w[5, 3:7] = 1.0
    got = score_views("v", photo, [render], [w], mode="compat", lpips_spatial=spatial)[0].masked_lpips
    lmap = _stand_in_map(render.transpose(2, 0, 1), photo.transpose(2, 0, 1), normalize=False)
    assert abs(got - np.sum(lmap * w) / np.sum(w)) <= TOL


def test_a_splat_method_is_compared_for_fid_by_its_renders_at_the_test_views(models, fid_calls, tmp_path):
    """A method given as a splat scene has no folder of renders: FID and KID compare the photographs'
    folder with its renders at the test views, as rendered and scored (LPIPS is computed on them too)."""
    from tests.test_inpaint_splats import _renders
    from r360gpu.synthetic.inpaint_splats import write_usid_splat_example

    root = write_usid_splat_example(tmp_path / "ex", n_test=3, n_train=2)
    out = tmp_path / "out"
    args = ["inpaint", "360usid", str(root / "data"), f"hole={root}/output/{{scene}}/hole.ply", "--masks",
            f"{root}/output/{{scene}}/object_mask", "--out", str(out), "--quiet",
            *_with_models(models, "plain", "inception")]
    assert main(args) == 0
    (ref, got, what), = fid_calls
    inception = InceptionModel(models["inception"])
    photos, renders = _renders(root, "hole")
    from r360gpu.io.inpaint_folders import read_image
    np.testing.assert_array_equal(ref, inception.features([read_image(p) for p in fid_image_files(photos[0].parent)]))
    np.testing.assert_allclose(got, inception.features(renders), atol=1e-6)
    doc = dec_tree(json.loads((out / "results.json").read_text()))
    entry = doc["scenes"]["room"]["hole"]
    assert entry["fid"] == 101.0 and entry["n_out"] == len(renders)
    assert all(v["lpips"] is not None for v in entry["views"])
