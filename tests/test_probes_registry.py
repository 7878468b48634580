"""parse_probe_spec: every probe kind built from its command-line spec, and the
errors for malformed specs."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes.precomputed import PrecomputedSemanticProbe, PrecomputedStructuralProbe
from r360gpu.probes.registry import PROBE_KINDS, parse_probe_spec



def test_builtin_names_defaults_and_axes():
    from r360gpu.probes.builtin_semantic import BuiltinAppearanceProbe
    from r360gpu.probes.builtin_structural import BuiltinStructuralProbe
    from r360gpu.probes.registry import BUILTIN_PROBES, DEFAULT_PROBES, default_probes, probe_for_axis
    from r360gpu.pipeline import default_probes as scoring_defaults

    assert set(BUILTIN_PROBES) == {"builtin-appearance", "builtin-hierarchy", "builtin-graphseg", "builtin-slic"}
    for axis, name in DEFAULT_PROBES.items():
        assert BUILTIN_PROBES[name][0] == axis
    sem, stru = default_probes()
    assert [p.name for p in sem] == ["builtin-appearance"] and isinstance(stru[0], BuiltinStructuralProbe)
    s2, t2 = scoring_defaults()
    assert s2[0] is not sem[0] and (s2[0].describe(), t2[0].describe()) == (sem[0].describe(), stru[0].describe())
    assert isinstance(probe_for_axis(" Builtin ", "semantic"), BuiltinAppearanceProbe)
    assert probe_for_axis("builtin", "structural").describe() == stru[0].describe()
    assert stru[0].name == "builtin-hierarchy"
    assert probe_for_axis("builtin-graphseg", "structural").describe()["params"]["method"] == "graph"
    slic = probe_for_axis("builtin-slic", "structural")
    assert slic.describe() != stru[0].describe()
    with pytest.raises(InputError, match="is a structural probe, not a semantic one"):
        probe_for_axis("builtin-slic", "semantic")
    with pytest.raises(InputError, match="is a semantic probe, not a structural one"):
        probe_for_axis("builtin-appearance", "structural")
    with pytest.raises(InputError, match="expected KIND"):
        probe_for_axis("builtin-nothing", "semantic")


def test_fit_is_optional_and_flagged():
    from r360gpu.probes.base import MaskSet, StructuralProbe
    from r360gpu.probes.registry import builtin_probe

    class Plain(StructuralProbe):
        name = "plain"

        def params(self):
            return {}

        def predict(self, views):
            return [MaskSet.empty(*v.size) for v in views]

    plain = Plain()
    assert plain.learns_from_scene is False and plain.fit([np.zeros((2, 2, 3))], [np.ones((2, 2), bool)]) is plain
    assert builtin_probe("builtin-appearance").learns_from_scene is True
    assert builtin_probe("builtin-graphseg").learns_from_scene is False


pytest.importorskip("onnx")
from onnx_graphs import dino_model, sam_decoder, sam_encoder_nchw, write_tokenizer_json  # noqa: E402


@pytest.fixture()
def sam_files(tmp_path):
    enc = sam_encoder_nchw(tmp_path / "enc.onnx")
    dec = sam_decoder(tmp_path / "dec.onnx", iou=[0.9] * 4, radius=[100] * 4, slope=[1.0] * 4)
    return enc, dec


def test_kinds():
    assert PROBE_KINDS == ("sam", "grounded", "gsam2-json", "png", "sam-json")


def test_sam_spec_with_amg_params(sam_files):
    from r360gpu.probes.sam_amg import SamAmgProbe

    enc, dec = sam_files
    probe = parse_probe_spec(
        f"sam:encoder={enc},decoder={dec},points-per-side=16,pred_iou_thresh=0.9,crop_n_layers=1,"
        "crop_overlap_ratio=0.25,min_mask_region_area=100,device=cpu,name=mysam"
    )
    assert isinstance(probe, SamAmgProbe) and probe.name == "mysam"
    amg = probe.describe()["params"]["amg"]
    assert (amg["points_per_side"], amg["pred_iou_thresh"], amg["crop_n_layers"]) == (16, 0.9, 1)
    assert (amg["crop_overlap_ratio"], amg["min_mask_region_area"], amg["points_per_batch"]) == (0.25, 100, 64)
    default = parse_probe_spec(f"sam:encoder={enc},decoder={dec},pred_iou_thresh=default")
    assert default.name == "sam-amg" and default.describe()["params"]["amg"]["pred_iou_thresh"] == 0.88


def test_grounded_spec(tmp_path, sam_files):
    pytest.importorskip("tokenizers")
    from r360gpu.probes.grounded import GroundedSamProbe

    tok = write_tokenizer_json(tmp_path / "tokenizer.json")
    dino = dino_model(tmp_path / "dino.onnx", np.zeros((2, 256), np.float32), np.zeros((2, 4), np.float32))
    enc, dec = sam_files
    probe = parse_probe_spec(
        f"grounded:dino={dino},tokenizer={tok},sam-encoder={enc},sam-decoder={dec},"
        "box_threshold=0.3,text-threshold=0.2,phrase_match=no"
    )
    assert isinstance(probe, GroundedSamProbe) and probe.name == "grounded-sam"
    g = probe.describe()["params"]["grounding"]
    assert (g["box_threshold"], g["text_threshold"], g["phrase_match"]) == (0.3, 0.2, False)


def _png(path: Path, mask: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), mask.astype(np.uint8) * 255)


def test_png_spec_remove360_layout(tmp_path):
    root = tmp_path / "gsam2"
    _png(root / "before" / "mask" / "00001.png", np.ones((4, 5), bool))
    _png(root / "after" / "mask" / "00001.png", np.zeros((4, 5), bool))
    probe = parse_probe_spec(f"png:{root}")
    assert isinstance(probe, PrecomputedSemanticProbe)
    assert probe.params()["paths"] == {"post": str(root / "after" / "mask"), "pre": str(root / "before" / "mask")}
    assert probe.params()["format"] == "png"


def test_explicit_rendering_dirs(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    probe = parse_probe_spec(f"gsam2-json:pre={tmp_path / 'a'},post={tmp_path / 'b'},name=gs")
    assert isinstance(probe, PrecomputedSemanticProbe) and probe.name == "gs"
    assert probe.params()["format"] == "gsam2-json"
    assert set(probe.params()["paths"]) == {"pre", "post"}


def test_sam_json_spec(tmp_path):
    (tmp_path / "sam" / "after").mkdir(parents=True)
    (tmp_path / "sam" / "after" / "00001.json").write_text("[]")
    (tmp_path / "sam" / "before").mkdir(parents=True)
    probe = parse_probe_spec(f"sam-json:{tmp_path / 'sam'}")
    assert isinstance(probe, PrecomputedStructuralProbe)
    assert probe.params()["paths"] == {"post": str(tmp_path / "sam" / "after"), "pre": str(tmp_path / "sam" / "before")}
    named = parse_probe_spec(f"sam-json:ref={tmp_path / 'sam' / 'after'}")
    assert named.params()["paths"] == {"ref": str(tmp_path / "sam" / "after")}


@pytest.mark.parametrize(
    "spec, message",
    [
        ("nonsense", "expected KIND"),
        ("yolo:x=1", "expected KIND"),
        ("sam:", "nothing after"),
        ("sam:encoder=a.onnx", "missing decoder"),
        ("grounded:dino=a,tokenizer=b", "missing sam-encoder, sam-decoder"),
        ("sam:encoder=a,decoder=b,encoder=c", "given twice"),
        ("sam:encoder=a,decoder=b,colour=red", "unknown option"),
        ("sam:encoder=a,decoder=b,points_per_side=many", "not a valid int"),
        ("sam:encoder=a,decoder=b,points_per_side", "not KEY=VALUE"),
        ("grounded:dino=a,tokenizer=b,sam-encoder=c,sam-decoder=d,phrase_match=maybe", "not a valid bool"),
        ("grounded:dino=a,tokenizer=b,sam-encoder=c,sam-decoder=d,box_threshold=high", "not a valid float"),
        ("png:/no/such/dir", "does not exist"),
        ("png:pre=x,side=y", "unknown key"),
    ],
)
def test_bad_specs(spec, message):
    with pytest.raises(InputError, match=message) as err:
        parse_probe_spec(spec)
    assert spec.split(",")[0] in str(err.value)


def test_bad_spec_values_reach_the_probe_checks(sam_files):
    enc, dec = sam_files
    with pytest.raises(InputError, match="box_nms_thresh"):
        parse_probe_spec(f"sam:encoder={enc},decoder={dec},box_nms_thresh=2")
    with pytest.raises(InputError, match="pred_iou_thresh"):
        parse_probe_spec(f"sam:encoder={enc},decoder={dec},pred_iou_thresh=nan")
    with pytest.raises(InputError, match="does not exist"):
        parse_probe_spec(f"sam:encoder={enc},decoder={dec.parent / 'missing.onnx'}")
    with pytest.raises(InputError, match="unknown device"):
        parse_probe_spec(f"sam:encoder={enc},decoder={dec},device=tpu")


def test_directory_without_rendering_folders(tmp_path):
    (tmp_path / "flat").mkdir()
    with pytest.raises(InputError, match="per-rendering sub-folder"):
        parse_probe_spec(f"png:{tmp_path / 'flat'}")
