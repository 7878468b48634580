"""Importers of precomputed masks (Grounded-SAM-2 JSON, PNG folders, SAM JSON)
and the probes that serve them.  Fixtures follow the upstream formats exactly:
tests/data/probes/ holds hand-checked files, the rest are written here the
way the upstream scripts write them."""
from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.probes import rle
from r360gpu.probes.base import ProbeView
from r360gpu.probes.gsam2_dumps import Gsam2JsonDir, read_gsam2_json
from r360gpu.probes.mask_dirs import PngMaskDir, read_mask_png
from r360gpu.probes.precomputed import PrecomputedSemanticProbe, PrecomputedStructuralProbe, remove360_sources
from r360gpu.probes.prompt_rule import label_matches, prompt_phrases
from r360gpu.probes.sam_records import SamJsonDir, read_sam_json
from r360gpu.util.resize import resize_nearest

DATA = Path(__file__).parent / "data" / "probes"

SOFA = np.array([[0, 0, 0, 0, 0], [0, 1, 1, 1, 0], [0, 1, 1, 1, 0], [0, 0, 0, 0, 0]], bool)
CORNERS = np.array([[0, 0, 0, 0, 1], [0, 0, 0, 0, 0], [0, 0, 0, 0, 0], [1, 0, 0, 0, 0]], bool)
TOP_ROW = np.array([[1, 1, 1, 1, 1], [0, 0, 0, 0, 0], [0, 0, 0, 0, 0], [0, 0, 0, 0, 0]], bool)


def _gsam2_dump(image_path, annotations, h, w):
    """A dump as Grounded-SAM-2's demos write it (DUMP_JSON_RESULTS=True)."""
    return {
        "image_path": image_path,
        "annotations": [
            {"class_name": name, "bbox": [0.0, 0.0, float(w), float(h)], "segmentation": rle.encode(mask), "score": score}
            for name, mask, score in annotations
        ],
        "box_format": "xyxy",
        "img_width": w,
        "img_height": h,
    }


def _write_json(path: Path, obj, indent=4):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=indent))


def _post(name, h=4, w=5):
    return ProbeView(name, rendering="post", size=(h, w))


# --- prompt rule -------------------------------------------------------------


@pytest.mark.parametrize(
    "class_name, prompt, kept",
    [
        ("sofa", "sofa", True),
        ("Sofa", "sofa.", True),
        ("  sofa ", "SOFA", True),
        ("white  chair", "White chair.", True),
        ("couch", "sofa. couch.", True),
        ("sofa cushion", "sofa", False),
        ("sofa", "sofa cushion", False),
        ("chair", "sofa", False),
        ("anything", "", True),
        ("anything", " . ", True),
    ],
)
def test_prompt_rule(class_name, prompt, kept):
    assert label_matches(class_name, prompt) is kept


def test_prompt_phrases():
    assert prompt_phrases("Sofa.  White   Chair. ") == ["sofa", "white chair"]


# --- Grounded-SAM-2 JSON -------------------------------------------------------


def test_gsam2_static_fixture_by_image_path():
    source = Gsam2JsonDir(DATA / "gsam2")
    # The demo writes a fixed file name; the view is named by image_path's stem.
    assert source.names() == ["00003"]
    pred = source.read("00003", "sofa.")
    assert pred.labels == ["sofa"] and pred.size == (4, 5)
    np.testing.assert_allclose(pred.scores, [0.87], rtol=1e-6)
    assert np.array_equal(pred.masks[0], SOFA)
    both = source.read("00003", "sofa. chair.")
    assert both.labels == ["sofa", "chair"]
    np.testing.assert_allclose(both.scores, [0.87, 0.42], rtol=1e-6)
    assert np.array_equal(both.union(), SOFA | CORNERS)
    assert source.read("00004", "sofa") is None


def test_gsam2_filters_and_unions(tmp_path):
    h, w = 6, 7
    rng = np.random.default_rng(3)
    masks = [rng.random((h, w)) < 0.3 for _ in range(4)]
    anns = [("sofa", masks[0], [0.9]), ("Sofa", masks[1], 0.5), ("chair", masks[2], [0.8]), ("sofa cushion", masks[3], 0.7)]
    _write_json(tmp_path / "00001.json", _gsam2_dump("", anns, h, w))
    pred = read_gsam2_json(tmp_path / "00001.json", "sofa", probe="g")
    assert pred.labels == ["sofa", "Sofa"] and pred.probe == "g"
    np.testing.assert_allclose(pred.scores, [0.9, 0.5], rtol=1e-6)
    assert np.array_equal(pred.union(), masks[0] | masks[1])
    # No image_path: the file stem names the view.
    assert Gsam2JsonDir(tmp_path).names() == ["00001"]
    assert read_gsam2_json(tmp_path / "00001.json", "table").count == 0
    assert read_gsam2_json(tmp_path / "00001.json", "").count == 4


def test_gsam2_without_declared_size(tmp_path):
    dump = _gsam2_dump("x.png", [("sofa", SOFA, 0.3)], 4, 5)
    del dump["img_width"], dump["img_height"]
    _write_json(tmp_path / "a.json", dump)
    assert read_gsam2_json(tmp_path / "a.json", "sofa").size == (4, 5)
    _write_json(tmp_path / "b.json", {"image_path": "y.png", "annotations": []})
    assert read_gsam2_json(tmp_path / "b.json", "sofa").count == 0


def test_gsam2_matches_pycocotools_dump(tmp_path):
    mask_utils = pytest.importorskip("pycocotools.mask")
    mask = np.zeros((9, 11), np.uint8)
    mask[2:7, 3:10] = 1
    # Exactly the demos' single_mask_to_rle.
    seg = mask_utils.encode(np.array(mask[:, :, None], order="F", dtype="uint8"))[0]
    seg["counts"] = seg["counts"].decode("utf-8")
    dump = {"image_path": "r/00009.png", "annotations": [{"class_name": "sofa", "bbox": [3, 2, 10, 7],
            "segmentation": seg, "score": [0.75]}], "box_format": "xyxy", "img_width": 11, "img_height": 9}
    _write_json(tmp_path / "out.json", dump)
    pred = read_gsam2_json(tmp_path / "out.json", "sofa")
    assert np.array_equal(pred.masks[0], mask.astype(bool))


@pytest.mark.parametrize(
    "mutate, fragment",
    [
        (lambda d: d["annotations"][0]["segmentation"].update(counts="5220"), "counts sum to"),
        (lambda d: d.update(img_width=6), "segmentation is 4x5 but the image is 4x6"),
        (lambda d: d["annotations"][0].update(score=[0.1, 0.2]), "one element"),
        (lambda d: d["annotations"][0].update(score="high"), "'score' must be"),
        (lambda d: d["annotations"][0].update(segmentation=[[0, 1]]), "COCO RLE object"),
        (lambda d: d["annotations"][0].pop("class_name"), "'class_name'"),
        (lambda d: d.pop("annotations"), "'annotations' list"),
        (lambda d: d.update(img_height=0), "'img_height'"),
    ],
)
def test_gsam2_bad_input(tmp_path, mutate, fragment):
    dump = json.loads((DATA / "gsam2" / "grounded_sam2_local_image_demo_results.json").read_text())
    mutate(dump)
    path = tmp_path / "bad.json"
    _write_json(path, dump)
    with pytest.raises(InputError) as err:
        read_gsam2_json(path, "sofa")
    assert str(path) in str(err.value) and fragment in str(err.value)


def test_malformed_json_names_the_file(tmp_path):
    path = tmp_path / "00001.json"
    path.write_text('{"annotations": [}')
    with pytest.raises(InputError, match="malformed JSON") as err:
        Gsam2JsonDir(tmp_path)
    assert str(path) in str(err.value)
    with pytest.raises(InputError, match="malformed JSON"):
        read_sam_json(path)


def test_gsam2_two_files_for_one_view(tmp_path):
    _write_json(tmp_path / "a.json", _gsam2_dump("r/00001.png", [], 4, 5))
    _write_json(tmp_path / "00001.json", _gsam2_dump("", [], 4, 5))
    with pytest.raises(InputError, match="describes view '00001'"):
        Gsam2JsonDir(tmp_path)


# --- PNG folders ---------------------------------------------------------------


def test_png_masks(tmp_path):
    cv2.imwrite(str(tmp_path / "gray.png"), SOFA.astype(np.uint8) * 255)
    cv2.imwrite(str(tmp_path / "low.png"), SOFA.astype(np.uint8))  # value 1 counts too
    colour = np.zeros((4, 5, 3), np.uint8)
    colour[CORNERS] = (0, 0, 1)  # a faint red only in one channel
    cv2.imwrite(str(tmp_path / "colour.png"), colour)
    rgba = np.zeros((4, 5, 4), np.uint8)
    rgba[..., 3] = 255  # opaque everywhere: alpha is not the mask
    rgba[TOP_ROW, 1] = 9
    cv2.imwrite(str(tmp_path / "rgba.png"), rgba)
    cv2.imwrite(str(tmp_path / "wide.png"), (SOFA.astype(np.uint16) * 40000))
    for name, expected in [("gray", SOFA), ("low", SOFA), ("colour", CORNERS), ("rgba", TOP_ROW), ("wide", SOFA)]:
        assert np.array_equal(read_mask_png(tmp_path / f"{name}.png"), expected), name
    (tmp_path / "broken.png").write_bytes(b"\x89PNG not really")
    with pytest.raises(InputError, match="cannot decode mask image") as err:
        read_mask_png(tmp_path / "broken.png")
    assert "broken.png" in str(err.value)


def test_png_source_predictions(tmp_path):
    cv2.imwrite(str(tmp_path / "00001.png"), SOFA.astype(np.uint8) * 255)
    cv2.imwrite(str(tmp_path / "00002.png"), np.zeros((4, 5), np.uint8))
    source = PngMaskDir(tmp_path)
    assert source.names() == ["00001", "00002"]
    pred = source.read("00001", "sofa")
    assert pred.count == 1 and pred.labels == ["sofa"] and np.isnan(pred.scores[0])
    assert np.array_equal(pred.union(), SOFA)
    assert source.read("00002", "sofa").count == 0
    assert source.read("00003", "sofa") is None


# --- SAM automatic-mask JSON ---------------------------------------------------


def test_sam_static_fixture():
    masks = read_sam_json(DATA / "sam" / "00003.json", probe="s")
    assert masks.count == 2 and masks.size == (4, 5) and masks.scores is None and masks.probe == "s"
    assert np.array_equal(masks.masks[0], SOFA) and np.array_equal(masks.masks[1], TOP_ROW)


def test_sam_record_variants(tmp_path):
    records = [
        {"segmentation": SOFA.astype(int).tolist(), "area": 6, "bbox": [1, 1, 3, 2], "predicted_iou": 0.9},
        {"segmentation": rle.encode(CORNERS), "area": 2, "bbox": [0, 0, 5, 4], "predicted_iou": 0.8},
        {"mask": TOP_ROW.tolist(), "area": 5, "bbox": [0, 0, 5, 1], "predicted_iou": 0.7},
        {"segmentation": rle.encode(SOFA, compressed=False), "area": 6, "bbox": [1, 1, 3, 2], "predicted_iou": 0.6},
    ]
    _write_json(tmp_path / "00001.json", records, indent=None)
    got = read_sam_json(tmp_path / "00001.json")
    assert got.count == 4
    for m, expected in zip(got.masks, [SOFA, CORNERS, TOP_ROW, SOFA]):
        assert np.array_equal(m, expected)
    np.testing.assert_allclose(got.scores, [0.9, 0.8, 0.7, 0.6], rtol=1e-6)
    _write_json(tmp_path / "00002.json", [])
    assert read_sam_json(tmp_path / "00002.json").count == 0


@pytest.mark.parametrize(
    "records, fragment",
    [
        ([{"segmentation": [[0, 1], [1]], "area": 2}], "different lengths"),
        ([{"segmentation": [[0, 2], [1, 0]]}], "0/1"),
        ([{"segmentation": [["a", "b"]]}], "0/1"),
        ([{"segmentation": [0, 1, 1]}], "H x W"),
        ([{"segmentation": SOFA.tolist()}, {"segmentation": [[True]]}], "record 1: segmentation is 1x1, record 0 is 4x5"),
        ([{"area": 3, "bbox": [0, 0, 1, 1]}], "no 'segmentation'"),
        ([{"segmentation": {"size": [4, 5], "counts": [3, 3]}}], "counts sum to 6"),
        ({"segmentation": []}, "list of records"),
        (["x"], "record 0 is not an object"),
    ],
)
def test_sam_bad_input(tmp_path, records, fragment):
    path = tmp_path / "00001.json"
    _write_json(path, records)
    with pytest.raises(InputError) as err:
        read_sam_json(path)
    assert str(path) in str(err.value) and fragment in str(err.value)


def test_sam_merged_json_wins(tmp_path):
    _write_json(tmp_path / "merged.json", {"00001.png": [{"segmentation": SOFA.tolist()}], "00002": []})
    _write_json(tmp_path / "00001.json", [{"segmentation": TOP_ROW.tolist()}])
    source = SamJsonDir(tmp_path)
    assert source.names() == ["00001", "00002"]
    assert np.array_equal(source.read("00001").masks[0], SOFA)
    assert source.read("00002").count == 0
    assert source.read("00003") is None
    _write_json(tmp_path / "merged.json", {"00001": [{"segmentation": [[3]]}]})
    with pytest.raises(InputError, match="view '00001': record 0") as err:
        SamJsonDir(tmp_path).read("00001")
    assert "merged.json" in str(err.value)


# --- probes: missing files, resizing, renderings ---------------------------------


def test_semantic_probe_missing_and_resized(tmp_path):
    small = np.zeros((8, 10), bool)
    small[2:5, 3:9] = True
    for name in ("00001", "00002"):
        _write_json(tmp_path / "after" / f"{name}.json", _gsam2_dump("", [("sofa", small, [0.6])], 8, 10))
    probe = PrecomputedSemanticProbe.from_dirs({"post": tmp_path / "after"}, name="gsam2-dump")
    views = [_post(n, 16, 20) for n in ("00001", "00002", "00003", "00004")]
    with pytest.warns(R360Warning) as record:
        preds = probe.predict(views, "sofa")
    messages = [str(r.message) for r in record]
    assert len(messages) == 2  # one resize warning and one missing-file warning, not one per file
    assert any("resized with nearest neighbour" in m and "00001.json" in m for m in messages)
    assert any("no precomputed mask" in m and "00003.json" in m for m in messages)
    assert probe.missing_count == 2
    assert probe.stats.as_dict() == {
        "missing_count": 2,
        "missing": ["post/00003", "post/00004"],
        "resized_count": 2,
        "resized": ["post/00001", "post/00002"],
    }
    assert all(p.size == (16, 20) and p.probe == "gsam2-dump" for p in preds)
    assert np.array_equal(preds[0].union(), resize_nearest(small, (16, 20)))
    assert preds[0].union().sum() == 4 * small.sum()
    assert preds[2].count == 0 and not preds[2].union().any()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no further warnings, no double counting
        probe.predict(views, "sofa")
    assert probe.missing_count == 2


def test_structural_probe_roles_and_describe(tmp_path):
    scene = tmp_path / "scene"
    (scene / "sam" / "after").mkdir(parents=True)
    shutil.copy(DATA / "sam" / "00003.json", scene / "sam" / "after" / "00003.json")
    (scene / "gsam2" / "after" / "mask").mkdir(parents=True)
    cv2.imwrite(str(scene / "gsam2" / "after" / "mask" / "00003.png"), SOFA.astype(np.uint8) * 255)
    found = remove360_sources(scene)
    assert found == {"semantic": {"post": scene / "gsam2/after/mask"}, "structural": {"post": scene / "sam/after"}}

    sam = PrecomputedStructuralProbe.from_dirs(found["structural"])
    [ms] = sam.predict([_post("00003")])
    assert ms.count == 2 and ms.probe == "sam-precomputed"
    assert sam.cacheable is False
    d = sam.describe()
    assert d["name"] == "sam-precomputed" and d["kind"] == "structural" and d["models"] == {}
    assert d["params"] == {"source": "precomputed", "format": "sam-json", "paths": {"post": str(scene / "sam/after")}}

    sem = PrecomputedSemanticProbe.from_dirs(found["semantic"], name="gsam2-png")
    [pred] = sem.predict([_post("00003")], "sofa")
    assert np.array_equal(pred.union(), SOFA)
    assert sem.describe()["params"]["format"] == "png"

    with pytest.raises(InputError, match="needs to know which rendering"):
        sem.predict([ProbeView("00003", size=(4, 5))], "sofa")
    with pytest.raises(InputError, match="no precomputed masks for the 'ref' rendering"):
        sam.predict([ProbeView("00003", size=(4, 5), rendering="ref")])


def test_structural_probe_missing_and_resized(tmp_path):
    _write_json(tmp_path / "00001.json", [{"segmentation": SOFA.tolist()}], indent=None)
    probe = PrecomputedStructuralProbe.from_dirs({"ref": tmp_path}, name="sam-ref")
    with pytest.warns(R360Warning):
        out = probe.predict([ProbeView("00001", size=(8, 10), rendering="ref"), ProbeView("00002", size=(8, 10), rendering="ref")])
    assert np.array_equal(out[0].masks[0], np.kron(SOFA, np.ones((2, 2), bool)))
    assert out[1].count == 0 and out[1].size == (8, 10)
    assert probe.stats.missing == ["ref/00002"] and probe.stats.resized == ["ref/00001"]


def test_auto_format_and_missing_dirs(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        PrecomputedSemanticProbe.from_dirs({"post": tmp_path / "nope"})
    (tmp_path / "mixed").mkdir()
    (tmp_path / "mixed" / "a.png").write_bytes(b"")
    (tmp_path / "mixed" / "a.json").write_text("{}")
    with pytest.raises(InputError, match="name the format"):
        PrecomputedSemanticProbe.from_dirs({"post": tmp_path / "mixed"})
    with pytest.raises(ValueError):
        PrecomputedSemanticProbe.from_dirs({"after": tmp_path / "mixed"}, format="png")


def test_resize_nearest_matches_opencv():
    rng = np.random.default_rng(5)
    for (h, w), (oh, ow) in [((4, 5), (8, 10)), ((7, 3), (13, 11)), ((480, 640), (270, 360)), ((33, 67), (100, 100))]:
        m = rng.random((h, w)) < 0.5
        ours = resize_nearest(m, (oh, ow))
        ref = cv2.resize(m.astype(np.uint8), (ow, oh), interpolation=cv2.INTER_NEAREST) > 0
        assert np.array_equal(ours, ref)
        stack = resize_nearest(np.stack([m, ~m]), (oh, ow))
        assert np.array_equal(stack[0], ours) and np.array_equal(stack[1], ~ours)
    assert resize_nearest(np.zeros((0, 0, 0), bool), (3, 4)).shape == (0, 3, 4)
