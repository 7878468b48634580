"""SAM automatic masks and the grounded probe on onnxruntime, run on the tiny
stand-in graphs of tests/onnx_graphs.py: model loading, variant detection,
preprocessing as seen by the encoders, prompt encoding as seen by the
decoders, the AMG filters and the GroundingDINO post-processing, each
against hand-computed results.  Grounded tests need the optional
``tokenizers`` package (skipped without it)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
from onnx import helper  # noqa: E402

from r360gpu.errors import InputError, R360Warning  # noqa: E402
from r360gpu.probes import amg_utils as au  # noqa: E402
from r360gpu.probes.base import ProbeView  # noqa: E402
from r360gpu.probes.cache import ProbeCache, cached  # noqa: E402
from r360gpu.probes.onnx_models import (  # noqa: E402
    OnnxModel,
    SamEmbedding,
    SamModels,
    available_providers,
    external_data_files,
    providers_for,
)
from r360gpu.probes.preprocess import IMAGENET_MEAN, IMAGENET_STD, SAM_PIXEL_MEAN, SAM_PIXEL_STD  # noqa: E402
from r360gpu.probes.preprocess import resize_logits as pp_resize_logits  # noqa: E402
from r360gpu.probes.sam_amg import AmgParams, SamAmgProbe, _remove_small_regions, generate_masks  # noqa: E402

from onnx_graphs import (  # noqa: E402
    VOCAB,
    F,
    const,
    dino_model,
    record,
    sam2_decoder,
    sam2_encoder,
    sam_decoder,
    sam_encoder_hwc,
    sam_encoder_nchw,
    save_model,
    value_info,
    write_tokenizer_json,
)


def _disk(h, w, cx, cy, r):
    """Image pixels whose centre, mapped to the 1024 frame (scale s), lies within r of (cx, cy) there."""
    s = 1024 / max(h, w)
    ys, xs = np.mgrid[0:h, 0:w]
    fx = (xs + 0.5) * s - 0.5
    fy = (ys + 0.5) * s - 0.5
    return (fx - cx) ** 2 + (fy - cy) ** 2 < r * r


def _iou(a, b):
    return (a & b).sum() / max((a | b).sum(), 1)


# SAM decoder tokens for the AMG tests (radii in 1024-frame pixels; 16 frame px = 1 image px at 64 x 64):
# token 0 (single-mask output, must be ignored): r 80, IoU 0.99
# token 1: r 160, IoU 0.95, sharp -> kept
# token 2: r 168, IoU 0.92, sharp -> removed by box NMS (box IoU with token 1 ~ 0.9)
# token 3: r 240, IoU 0.93, shallow slope -> unstable, removed
SAM_TOKENS = dict(iou=[0.99, 0.95, 0.92, 0.93], radius=[80, 160, 168, 240], slope=[1.0, 1.0, 1.0, 1e-5])


@pytest.fixture()
def sam_pair(tmp_path):
    enc = sam_encoder_nchw(tmp_path / "sam.encoder.onnx")
    dec = sam_decoder(tmp_path / "sam.decoder.onnx", **SAM_TOKENS)
    return enc, dec


# ============================================================ providers / sessions


def test_providers():
    assert providers_for("cpu") == ["CPUExecutionProvider"]
    assert providers_for("CPU") == ["CPUExecutionProvider"]
    auto = providers_for("auto")
    assert auto[-1] == "CPUExecutionProvider" and auto[0] in available_providers()
    with pytest.raises(InputError, match="unknown device"):
        providers_for("tpu")
    if "CUDAExecutionProvider" not in available_providers():
        with pytest.raises(InputError, match="CUDAExecutionProvider"):
            providers_for("cuda")


def test_missing_and_broken_model_files(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        OnnxModel(tmp_path / "nope.onnx")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(InputError, match="junk.onnx"):
        OnnxModel(junk, role="SAM image encoder")


def test_external_data_files_are_hashed(tmp_path):
    path = tmp_path / "ext.onnx"
    nodes = [helper.make_node("Add", ["x", "w"], ["y"])]
    graph = helper.make_graph(
        nodes, "g", [value_info("x", F, [4])], [value_info("y", F, [4])], [const("w", [1, 2, 3, 4])]
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8)
    onnx.save_model(
        model,
        str(path),
        save_as_external_data=True,
        all_tensors_to_one_file=True,
        location="ext_weights.bin",
        size_threshold=0,
    )
    assert [p.name for p in external_data_files(path)] == ["ext_weights.bin"]
    m = OnnxModel(path)
    digests = m.digests()
    assert set(digests) == {"ext.onnx", "ext_weights.bin"}
    out = m.run({"x": np.zeros(4)})["y"]  # feeds are cast to float32
    assert out.tolist() == [1, 2, 3, 4]
    # other weights beside the same graph file: another hash
    (tmp_path / "ext_weights.bin").write_bytes((tmp_path / "ext_weights.bin").read_bytes()[::-1])
    changed = OnnxModel(path).digests()
    assert changed["ext.onnx"] == digests["ext.onnx"] and changed["ext_weights.bin"] != digests["ext_weights.bin"]


@pytest.mark.parametrize("offset", range(0, 40))
def test_external_data_names_across_scan_blocks(tmp_path, monkeypatch, offset):
    import r360gpu.probes.onnx_models as om

    monkeypatch.setattr(om, "_SCAN_BLOCK", 16)  # every entry straddles some block boundary
    (tmp_path / "a.bin").write_bytes(b"x")
    (tmp_path / "w.bin").write_bytes(b"y")
    data = bytearray(80)
    data[offset : offset + 16] = om._LOCATION_KEY + bytes([5]) + b"a.bin"
    data[60:76] = om._LOCATION_KEY + bytes([5]) + b"w.bin"
    # a match whose "length" is absurd is not a file name and must not stall the scan
    data[0:0] = om._LOCATION_KEY + b"\xff\xff\xff\xff\x0f"
    (tmp_path / "m.onnx").write_bytes(bytes(data))
    assert [p.name for p in external_data_files(tmp_path / "m.onnx")] == ["a.bin", "w.bin"]


# ============================================================ variant detection


def test_detects_sam_nchw_and_hwc(tmp_path, sam_pair):
    enc, dec = sam_pair
    models = SamModels(enc, dec)
    assert (models.variant, models.encoder_layout, models.input_size, models.batched) == (
        "sam",
        "nchw",
        (1024, 1024),
        False,
    )
    hwc = SamModels(sam_encoder_hwc(tmp_path / "hwc.onnx"), dec)
    assert (hwc.variant, hwc.encoder_layout) == ("sam", "hwc")


def test_detects_sam2(tmp_path):
    models = SamModels(
        sam2_encoder(tmp_path / "e.onnx"),
        sam2_decoder(tmp_path / "d.onnx", iou=[0.9] * 3, radius=[1] * 3, slope=[1] * 3),
    )
    assert (models.variant, models.encoder_layout, models.input_size, models.batched) == (
        "sam2",
        "nchw",
        (1024, 1024),
        True,
    )


def test_rejects_unknown_encoder_listing_signature(tmp_path, sam_pair):
    _, dec = sam_pair
    bad = save_model(
        tmp_path / "bad.onnx",
        [helper.make_node("Identity", ["images"], ["embeddings"])],
        [value_info("images", F, [1, 3, 1024, 1024])],
        [value_info("embeddings", F, [1, 3, 1024, 1024])],
    )
    with pytest.raises(InputError) as err:
        SamModels(bad, dec)
    text = str(err.value)
    assert "bad.onnx" in text and "images float[1, 3, 1024, 1024]" in text and "embeddings" in text


def test_rejects_mismatched_pair(tmp_path, sam_pair):
    enc, _ = sam_pair
    dec2 = sam2_decoder(tmp_path / "d2.onnx", iou=[0.9] * 3, radius=[1] * 3, slope=[1] * 3)
    with pytest.raises(InputError, match="needs a SAM decoder") as err:
        SamModels(enc, dec2)
    assert "high_res_feats_0" in str(err.value)  # what was found is listed
    with pytest.raises(InputError, match="needs a SAM2 decoder"):
        SamModels(sam2_encoder(tmp_path / "e2.onnx"), sam_pair[1])


# ============================================================ preprocessing through the encoders


def test_sam_embed_preprocessing_reaches_encoder(sam_pair):
    models = SamModels(*sam_pair)
    colour = np.array([0.5, 0.25, 1.0], np.float32)
    image = np.broadcast_to(colour, (32, 64, 3)).copy()
    emb = models.embed(image)
    assert emb.image_size == (32, 64) and emb.model_size == (512, 1024)
    feat = emb.features["image_embeddings"]
    # segment-anything takes uint8: 127.5 and 63.75 round to 128 and 64.
    expect = (np.array([128.0, 64.0, 255.0]) - np.array(SAM_PIXEL_MEAN)) / np.array(SAM_PIXEL_STD)
    for c in range(3):
        np.testing.assert_allclose(feat[0, c, :32], expect[c], rtol=1e-5)  # image rows 0..511
        assert not feat[0, c, 32:].any()  # padding
    assert not feat[0, 3:].any()


def test_sam_hwc_encoder_gets_resized_0_255_image(tmp_path, sam_pair):
    models = SamModels(sam_encoder_hwc(tmp_path / "hwc.onnx"), sam_pair[1])
    image = np.broadcast_to(np.array([10, 20, 30], np.uint8), (20, 10, 3)).copy()
    calls = record(models.encoder)
    emb = models.embed(image)
    assert calls[0]["input_image"].shape == (1024, 512, 3)
    np.testing.assert_allclose(emb.features["image_embeddings"][0, :3, 0, 0], [10, 20, 30], rtol=1e-5)
    assert emb.model_size == (1024, 512)


def test_sam2_embed_plain_resize_imagenet(tmp_path):
    models = SamModels(
        sam2_encoder(tmp_path / "e.onnx"),
        sam2_decoder(tmp_path / "d.onnx", iou=[0.9] * 3, radius=[1] * 3, slope=[1] * 3),
    )
    colour = np.array([0.1, 0.6, 0.9], np.float32)
    emb = models.embed(np.broadcast_to(colour, (30, 70, 3)).copy())
    assert emb.model_size == (1024, 1024)
    expect = (colour - np.array(IMAGENET_MEAN)) / np.array(IMAGENET_STD)
    for name in ("image_embed", "high_res_feats_0", "high_res_feats_1"):
        for c in range(3):
            np.testing.assert_allclose(emb.features[name][0, c], expect[c], rtol=1e-5)


# ============================================================ prompts


def test_sam_point_prompts_frame_padding_and_per_prompt_runs(sam_pair):
    models = SamModels(*sam_pair)
    image = np.zeros((33, 50, 3), np.uint8)  # resized 676 x 1024
    emb = models.embed(image)
    calls = record(models.decoder)
    decoded = models.predict_points(emb, np.array([[10.0, 20.0], [0.0, 33.0]]))
    assert len(calls) == 2  # the export fixes the prompt batch to 1
    first = calls[0]
    np.testing.assert_allclose(first["point_coords"], [[[10 * 1024 / 50, 20 * 676 / 33], [0.0, 0.0]]], rtol=1e-6)
    assert first["point_labels"].tolist() == [[1.0, -1.0]]
    assert first["mask_input"].shape == (1, 1, 256, 256) and not first["mask_input"].any()
    assert first["has_mask_input"].tolist() == [0.0]
    assert first["orig_im_size"].tolist() == [33, 50]
    assert decoded.logits.shape == (2, 4, 256, 256) and decoded.low_res
    np.testing.assert_allclose(decoded.iou, [SAM_TOKENS["iou"]] * 2)


def test_sam_box_prompts_corner_labels_no_padding(sam_pair):
    models = SamModels(*sam_pair)
    emb = models.embed(np.zeros((64, 32, 3), np.uint8))  # resized 1024 x 512, scale 16
    calls = record(models.decoder)
    models.predict_boxes(emb, np.array([[1.0, 2.0, 30.0, 60.0]]))
    np.testing.assert_allclose(calls[0]["point_coords"], [[[16, 32], [480, 960]]])
    assert calls[0]["point_labels"].tolist() == [[2.0, 3.0]]


def test_sam2_prompts_batched_in_square_frame(tmp_path):
    models = SamModels(
        sam2_encoder(tmp_path / "e.onnx"),
        sam2_decoder(tmp_path / "d.onnx", iou=[0.9] * 3, radius=[1] * 3, slope=[1] * 3),
    )
    emb = models.embed(np.zeros((48, 64, 3), np.uint8))
    calls = record(models.decoder)
    decoded = models.predict_points(emb, np.array([[16.0, 12.0], [32.0, 24.0], [0.0, 0.0]]))
    assert len(calls) == 1
    np.testing.assert_allclose(calls[0]["point_coords"][:, 0], [[256, 256], [512, 512], [0, 0]])
    assert calls[0]["point_coords"].shape == (3, 1, 2)  # SAM2 exports add their own padding point
    assert calls[0]["point_labels"].tolist() == [[1.0], [1.0], [1.0]]
    assert calls[0]["mask_input"].shape == (3, 1, 256, 256)
    assert decoded.logits.shape == (3, 3, 256, 256)


def test_sam2_point_coordinates_round_as_transform_coords(tmp_path):
    """SAM2Transforms.transform_coords(normalize=True) on SAM2's float32 points tensor:
    float32(x) / w, then * 1024, each rounded to float32 (not one float64 product)."""
    models = SamModels(
        sam2_encoder(tmp_path / "e.onnx"),
        sam2_decoder(tmp_path / "d.onnx", iou=[0.9] * 3, radius=[1] * 3, slope=[1] * 3),
    )
    emb = SamEmbedding({}, (301, 437), (1024, 1024))
    xy = np.random.default_rng(0).uniform(0, 437, (2000, 2)) * [1.0, 301 / 437]
    expect = (xy.astype(np.float32) / np.array([437, 301], np.float32)) * np.float32(1024)
    np.testing.assert_array_equal(models.to_model_coords(emb, xy), expect)
    one_rounding = (xy * np.array([1024 / 437, 1024 / 301])).astype(np.float32)
    assert (one_rounding != expect).any()  # the two recipes do differ on these points


def test_sam2_logits_reach_the_upsampling_unclamped(tmp_path):
    """SAM2ImagePredictor._predict upsamples the decoder's logits as they are and clamps
    only the low-res copy it returns: r360gpu must not clamp at +-32 before upsampling
    (where a +100 / -1000 neighbourhood crosses 0 moves)."""
    models = SamModels(
        sam2_encoder(tmp_path / "e.onnx"),
        sam2_decoder(tmp_path / "d.onnx", iou=[0.9] * 3, radius=[160] * 3, slope=[1.0] * 3),
    )
    emb = models.embed(np.zeros((600, 600, 3), np.uint8))  # upsampled 256 -> 600: uneven weights
    decoded = models.predict_points(emb, np.array([[300.0, 300.0]]))
    assert decoded.logits.max() > 160.0**2 * 0.99  # the disk's centre value, R^2
    assert decoded.logits.min() < -32.0
    up = models.logits_to_image(emb, decoded.logits[0], decoded.low_res)
    np.testing.assert_array_equal(up, pp_resize_logits(decoded.logits[0], (600, 600)))
    clamped = pp_resize_logits(np.clip(decoded.logits[0], -32, 32), (600, 600))
    assert ((up > 0) != (clamped > 0)).any()


def test_decoder_without_low_res_uses_full_size_masks(tmp_path):
    enc = sam_encoder_nchw(tmp_path / "e.onnx")
    dec = sam_decoder(tmp_path / "d.onnx", low_res_output=False, **SAM_TOKENS)
    models = SamModels(enc, dec)
    emb = models.embed(np.zeros((64, 64, 3), np.uint8))
    decoded = models.predict_points(emb, np.array([[32.0, 32.0]]))
    assert not decoded.low_res and decoded.logits.shape == (1, 4, 64, 64)
    mask = models.logits_to_image(emb, decoded.multimask()[0][0, :1], decoded.low_res)[0] > 0
    assert _iou(mask, _disk(64, 64, 512, 512, 160)) > 0.9


def test_logits_to_image_sam_disk_location(sam_pair):
    models = SamModels(*sam_pair)
    emb = models.embed(np.zeros((64, 64, 3), np.uint8))
    decoded = models.predict_points(emb, np.array([[20.0, 40.0]]))
    logits, iou = decoded.multimask()
    np.testing.assert_allclose(iou[0], [0.95, 0.92, 0.93])
    mask = models.logits_to_image(emb, logits[0, :1], True)[0] > 0
    assert mask.shape == (64, 64)
    assert _iou(mask, _disk(64, 64, 320, 640, 160)) > 0.95
    ys, xs = np.nonzero(mask)
    assert abs(xs.mean() - 19.53) < 0.3 and abs(ys.mean() - 39.53) < 0.3  # centre 20*16 = 320 -> pixel 19.53


# ============================================================ automatic mask generator


def test_amg_sam_defaults_pick_token1_per_point(sam_pair):
    models = SamModels(*sam_pair)
    params = AmgParams(points_per_side=2)
    result = generate_masks(models, np.zeros((64, 64, 3), np.uint8), params)
    assert result.count == 4
    np.testing.assert_allclose(result.iou_preds, 0.95)
    assert (result.stability > 0.95).all()
    assert result.masks.shape == (4, 64, 64) and result.masks.dtype == bool
    points = sorted(map(tuple, result.points.tolist()))
    assert points == [(16.0, 16.0), (16.0, 48.0), (48.0, 16.0), (48.0, 48.0)]
    for mask, (px, py), box in zip(result.masks, result.points, result.boxes):
        assert _iou(mask, _disk(64, 64, px * 16, py * 16, 160)) > 0.95
        assert box.tolist() == au.masks_to_boxes(mask[None])[0].tolist()
    assert (result.crop_boxes == [0, 0, 64, 64]).all()


def test_amg_thresholds_change_the_result(sam_pair):
    models = SamModels(*sam_pair)
    image = np.zeros((64, 64, 3), np.uint8)
    # NMS off (threshold 1): token 2's disk (r 168) survives next to token 1's
    loose = generate_masks(models, image, AmgParams(points_per_side=2, box_nms_thresh=1.0))
    assert sorted(loose.iou_preds.tolist()) == pytest.approx([0.92] * 4 + [0.95] * 4)
    # no stability filter: token 3 (unstable) comes back too
    unstable = generate_masks(
        models, image, AmgParams(points_per_side=2, stability_score_thresh=0.0, box_nms_thresh=1.0)
    )
    assert unstable.count == 12
    # IoU threshold above 0.95 keeps nothing
    assert generate_masks(models, image, AmgParams(points_per_side=2, pred_iou_thresh=0.96)).count == 0
    # one batch per point gives the same masks as one batch for all
    per_point = generate_masks(models, image, AmgParams(points_per_side=2, points_per_batch=1))
    together = generate_masks(models, image, AmgParams(points_per_side=2))
    np.testing.assert_array_equal(
        per_point.masks[np.lexsort(per_point.points.T)], together.masks[np.lexsort(together.points.T)]
    )


def test_amg_sam2_default_iou_threshold(tmp_path):
    # tokens: r 160 IoU 0.95; r 80 IoU 0.85 (kept only under SAM2's 0.8 default); r 200 IoU 0.5
    dec = sam2_decoder(tmp_path / "d.onnx", iou=[0.95, 0.85, 0.5], radius=[160, 80, 200], slope=[1.0, 1.0, 1.0])
    models = SamModels(sam2_encoder(tmp_path / "e.onnx"), dec)
    result = generate_masks(models, np.zeros((64, 64, 3), np.uint8), AmgParams(points_per_side=2))
    assert sorted(result.iou_preds.tolist()) == pytest.approx([0.85] * 4 + [0.95] * 4)
    strict = generate_masks(models, np.zeros((64, 64, 3), np.uint8), AmgParams(points_per_side=2, pred_iou_thresh=0.88))
    assert strict.count == 4


def test_amg_sam2_non_square_frame(tmp_path):
    # slope 0.01 keeps the logits near the disk edge inside SAM2's +-32 clamp
    dec = sam2_decoder(tmp_path / "d.onnx", iou=[0.95, 0.5, 0.5], radius=[160, 1, 1], slope=[0.01, 1.0, 1.0])
    models = SamModels(sam2_encoder(tmp_path / "e.onnx"), dec)
    result = generate_masks(models, np.zeros((48, 64, 3), np.uint8), AmgParams(points_per_side=1))
    assert result.count == 1
    ys, xs = np.nonzero(result.masks[0])
    # the disk of radius 160 in the 1024 x 1024 frame is 10 px wide (x16) and 7.5 px tall (x21.33) in the image
    assert (xs.max() - xs.min() + 1) in (20, 21) and (ys.max() - ys.min() + 1) in (15, 16)
    assert abs(xs.mean() - 31.5) < 0.3 and abs(ys.mean() - 23.5) < 0.3


def test_amg_sam2_has_no_small_region_step(tmp_path):
    """SAM2AutomaticMaskGenerator.generate never calls postprocess_small_regions (segment-anything's
    does): min_mask_region_area only reaches SAM2's CUDA hole filling, so the masks stay as they are."""
    dec = sam2_decoder(tmp_path / "d.onnx", iou=[0.95, 0.5, 0.5], radius=[160, 1, 1], slope=[0.01, 1.0, 1.0])
    models = SamModels(sam2_encoder(tmp_path / "e.onnx"), dec)
    image = np.zeros((48, 64, 3), np.uint8)
    plain = generate_masks(models, image, AmgParams(points_per_side=1))
    big = generate_masks(models, image, AmgParams(points_per_side=1, min_mask_region_area=10**6))
    assert plain.count == big.count == 1 and plain.masks[0].sum() < 10**6
    np.testing.assert_array_equal(big.masks, plain.masks)  # SAM's step 5 would have removed this island


def test_amg_crop_layers(sam_pair):
    models = SamModels(*sam_pair)
    params = AmgParams(points_per_side=2, crop_n_layers=1)
    result = generate_masks(models, np.zeros((64, 64, 3), np.uint8), params)
    crops, _ = au.generate_crop_boxes((64, 64), 1, params.crop_overlap_ratio)
    assert crops[1:] == [[0, 0, 43, 43], [0, 22, 43, 64], [22, 0, 64, 43], [22, 22, 64, 64]]
    # Each ~43 px crop is encoded at 1024 (disk radius 160 / 23.8 = 6.7 px); of its 2 x 2 points
    # only the one near the image corner gives a mask not within 20 px of an inner crop edge.
    # Crop [22, 22, 64, 64] is 42 px: its points are at 10.5 and 31.5, i.e. 32.5 and 53.5.
    corner = {(10.75, 10.75), (10.75, 53.5), (53.5, 10.75), (53.5, 53.5)}
    whole = {(16.0, 16.0), (16.0, 48.0), (48.0, 16.0), (48.0, 48.0)}
    assert set(map(tuple, result.points.tolist())) == corner | whole
    for crop, box, point in zip(result.crop_boxes.tolist(), result.boxes, result.points.tolist()):
        assert crop == (
            [0, 0, 64, 64]
            if tuple(point) in whole
            else crops[1 + [(10.75, 10.75), (10.75, 53.5), (53.5, 10.75), (53.5, 53.5)].index(tuple(point))]
        )
        local = box - np.array([crop[0], crop[1], crop[0], crop[1]])
        assert not au.is_box_near_crop_edge(local[None], crop, [0, 0, 64, 64])[0]
    # The corner masks overlap the whole-image ones (box IoU ~0.25): crop NMS at 0 keeps
    # only the masks of the smaller crops.
    strict = generate_masks(
        models, np.zeros((64, 64, 3), np.uint8), AmgParams(points_per_side=2, crop_n_layers=1, crop_nms_thresh=0.0)
    )
    assert set(map(tuple, strict.points.tolist())) == corner


def test_amg_single_mask_decoder_warns(tmp_path):
    dec = sam_decoder(tmp_path / "d.onnx", iou=[0.95], radius=[160], slope=[1.0])
    models = SamModels(sam_encoder_nchw(tmp_path / "e.onnx"), dec)
    with pytest.warns(R360Warning, match="one mask per prompt"):
        result = generate_masks(models, np.zeros((64, 64, 3), np.uint8), AmgParams(points_per_side=1))
    assert result.count == 1


def test_amg_min_region_area_keeps_clean_disks(sam_pair):
    models = SamModels(*sam_pair)
    image = np.zeros((64, 64, 3), np.uint8)
    plain = generate_masks(models, image, AmgParams(points_per_side=2))
    # the disks have no holes and no islands, and the background is one large region
    cleaned = generate_masks(models, image, AmgParams(points_per_side=2, min_mask_region_area=50))
    np.testing.assert_array_equal(cleaned.masks, plain.masks)
    np.testing.assert_array_equal(cleaned.boxes, plain.boxes)
    # an area above a disk's (~314 px) and the background's would fill the background in as a "hole"
    flooded = generate_masks(models, image, AmgParams(points_per_side=2, min_mask_region_area=5000))
    assert flooded.count == 1 and flooded.masks[0].all()


def test_remove_small_regions_step_prefers_unchanged():
    masks = np.zeros((3, 20, 20), bool)
    masks[0, 2:12, 2:12] = True
    masks[0, 5, 5] = False  # a one-pixel hole: filled, so this mask changes
    masks[1, 2:12, 2:12] = True  # the same mask without the hole: unchanged
    masks[2, 15:18, 15:18] = True  # 9 px, away from the others
    masks[2, 0, 19] = True  # a one-pixel island: removed
    fixed, boxes, keep = _remove_small_regions(masks, 4, 0.7)
    # mask 0 equals mask 1 once filled; NMS visits the unchanged mask 1 (score 1) first
    assert keep.tolist() == [1, 2]
    np.testing.assert_array_equal(fixed[0], masks[1])
    assert fixed[1].sum() == 9 and boxes[1].tolist() == [15, 15, 17, 17]


def test_amg_params_validation_and_defaults():
    assert AmgParams().resolved("sam").pred_iou_thresh == 0.88
    assert AmgParams().resolved("sam2").pred_iou_thresh == 0.8
    assert AmgParams(pred_iou_thresh=0.5).resolved("sam2").pred_iou_thresh == 0.5
    d = AmgParams().as_dict()
    assert d["points_per_side"] == 32 and d["points_per_batch"] == 64 and d["stability_score_thresh"] == 0.95
    assert d["crop_overlap_ratio"] == pytest.approx(512 / 1500) and d["box_nms_thresh"] == 0.7
    for bad in (
        dict(points_per_side=0),
        dict(box_nms_thresh=1.5),
        dict(pred_iou_thresh=-0.1),
        dict(points_per_side=4, crop_n_layers=3, crop_n_points_downscale_factor=2),
        dict(min_mask_region_area=-1),
    ):
        with pytest.raises(InputError):
            AmgParams(**bad)


def test_sam_amg_probe_describe_and_cache(tmp_path, sam_pair):
    probe = SamAmgProbe(*sam_pair, params=AmgParams(points_per_side=2))
    assert probe.name == "sam-amg"
    desc = probe.describe()
    assert desc["kind"] == "structural"
    assert set(desc["models"]) == {"encoder:sam.encoder.onnx", "decoder:sam.decoder.onnx"}
    assert desc["params"]["amg"]["pred_iou_thresh"] == 0.88 and desc["params"]["variant"] == "sam"
    assert desc["params"]["provider"] == "CPUExecutionProvider"
    # the preprocessing is part of the key: masks cached under another resize must miss
    assert desc["params"]["image_resize"].startswith("PIL bilinear on the uint8 image")
    other = SamAmgProbe(*sam_pair, params=AmgParams(points_per_side=3))
    assert other.describe() != desc  # parameters are part of the cache key

    image = np.zeros((64, 64, 3), np.float32)
    views = [ProbeView("v0", image, "post"), ProbeView("v1", np.zeros((32, 48, 3), np.uint8), "post")]
    results = probe.predict(views)
    assert [r.size for r in results] == [(64, 64), (32, 48)]
    assert results[0].count == 4 and results[0].probe == "sam-amg"
    np.testing.assert_allclose(results[0].scores, 0.95)

    cache = ProbeCache(tmp_path / "cache")
    wrapped = cached(probe, cache)
    first = wrapped.predict(views[:1])
    again = wrapped.predict(views[:1])
    assert cache.hits == 1 and cache.misses == 1
    np.testing.assert_array_equal(first[0].masks, again[0].masks)

    with pytest.raises(InputError, match="needs the rendered image"):
        probe.predict([ProbeView("v2", None, "post", size=(4, 4))])


# ============================================================ grounded probe


@pytest.fixture()
def tokenizer_json(tmp_path):
    pytest.importorskip("tokenizers")
    return write_tokenizer_json(tmp_path / "tokenizer.json")


def _dino_outputs():
    """Caption "red sofa ." -> [CLS] red sofa . [SEP] (positions 0..4)."""
    q = 4
    logits = np.full((q, 256), -np.inf, np.float32)
    logits[:, :5] = -6.0
    logits[0, 1], logits[0, 2] = 2.0, 3.0  # "red sofa": kept, matches the prompt
    logits[1, 2], logits[1, 1] = -0.5, -2.0  # sigmoid 0.38 > 0.35: kept, phrase "sofa" (no match)
    logits[2, 2] = -1.0  # sigmoid 0.27 < 0.35: dropped
    logits[3, 1], logits[3, 4] = 1.0, 0.5  # phrase "red [SEP]"
    boxes = np.array(
        [[0.5, 0.5, 0.5, 0.5], [0.25, 0.25, 0.2, 0.2], [0.5, 0.5, 1.0, 1.0], [0.75, 0.75, 0.2, 0.2]], np.float32
    )
    return logits, boxes


@pytest.fixture()
def grounded_files(tmp_path, tokenizer_json):
    logits, boxes = _dino_outputs()
    dino = dino_model(tmp_path / "groundingdino.onnx", logits, boxes)
    enc = sam_encoder_nchw(tmp_path / "sam.encoder.onnx")
    # token 0 (single mask) is the box; tokens 1..3 are empty
    dec = sam_decoder(
        tmp_path / "sam.decoder.onnx",
        iou=[0.5, 0.9, 0.9, 0.9],
        shape="box",
        slope=[1, 1, 1, 1],
        offset=[0, -1e4, -1e4, -1e4],
    )
    return dino, tokenizer_json, enc, dec


def test_tokenizer_and_text_inputs(tokenizer_json):
    from r360gpu.probes.grounded import DinoTokenizer, caption_for, text_inputs

    tok = DinoTokenizer(tokenizer_json)
    assert caption_for("Red Sofa") == "red sofa ."
    assert caption_for(" sofa. ") == "sofa."
    with pytest.raises(InputError):
        caption_for(" . ")
    ids = tok.encode(caption_for("Red Sofa"))
    assert ids.tolist() == [2, 6, 7, 4, 3]
    assert tok.encode("sofa.").tolist() == ids[[0, 2, 3, 4]].tolist()
    feeds = text_inputs(ids, tok.special_ids)
    assert feeds["position_ids"].tolist() == [[0, 0, 1, 2, 0]]
    assert feeds["attention_mask"].tolist() == [[True] * 5]
    assert feeds["token_type_ids"].tolist() == [[0] * 5]
    expect = np.eye(5, dtype=bool)
    expect[1:4, 1:4] = True
    np.testing.assert_array_equal(feeds["text_token_mask"][0], expect)
    cut = text_inputs(ids, tok.special_ids, max_text_len=3)
    assert cut["input_ids"].shape == (1, 3) and cut["text_token_mask"].shape == (1, 3, 3)


def test_sub_sentence_masks_groundingdino_example():
    from r360gpu.probes.grounded import sub_sentence_masks

    # "the running dog ." -> [CLS] the running dog . [SEP] (hpc203's export example)
    ids = np.array([101, 1996, 2770, 3899, 1012, 102])
    mask, pos = sub_sentence_masks(ids, [101, 102, 1012, 1029])
    assert pos.tolist() == [0, 0, 1, 2, 3, 0]
    expect = np.eye(6, dtype=bool)
    expect[1:5, 1:5] = True
    np.testing.assert_array_equal(mask, expect)
    # two phrases: [CLS] a . b c . [SEP]
    ids = np.array([101, 7, 1012, 8, 9, 1012, 102])
    mask, pos = sub_sentence_masks(ids, [101, 102, 1012, 1029])
    assert pos.tolist() == [0, 0, 1, 0, 1, 2, 0]
    assert mask[1, 2] and not mask[1, 3] and mask[3, 5] and not mask[2, 3]


def test_decode_wordpiece_and_phrases():
    from r360gpu.probes.grounded import decode_wordpiece, phrase_from_posmap

    assert decode_wordpiece(["red", "sofa", "##s", "."]) == "red sofas."
    assert decode_wordpiece(["sofa", "[SEP]"]) == "sofa [SEP]"
    assert decode_wordpiece([]) == ""
    ids = np.array([2, 6, 7, 4, 3])
    pos = np.zeros(256, bool)
    pos[[0, 1, 2, 3]] = True  # [CLS] (index 0) is always excluded
    assert phrase_from_posmap(pos, ids, lambda i: VOCAB[i]) == "red sofa."
    pos[:] = False
    pos[[7, 255]] = True  # beyond the caption / at the 255 limit
    assert phrase_from_posmap(pos, ids, lambda i: VOCAB[i]) == ""


def test_decode_wordpiece_matches_tokenizers_decoder(tokenizer_json):
    import tokenizers

    from r360gpu.probes.grounded import decode_wordpiece

    tok = tokenizers.Tokenizer.from_file(str(tokenizer_json))
    for ids in ([6, 7, 10, 4, 3], [7, 4], [4, 7], [6, 1, 7], [2, 6], [10, 6], [5, 6, 5]):
        assert decode_wordpiece([VOCAB[i] for i in ids]) == tok.decode(ids, skip_special_tokens=False)


def test_select_detections_thresholds_and_boxes():
    from r360gpu.probes.grounded import cxcywh_to_xyxy, select_detections

    logits, boxes = _dino_outputs()
    ids = np.array([2, 6, 7, 4, 3])
    det = select_detections(logits, boxes, ids, lambda i: VOCAB[i], (64, 96))
    assert det.phrases == ["red sofa", "sofa", "red [SEP]"]
    np.testing.assert_allclose(
        det.scores, [1 / (1 + np.exp(-3.0)), 1 / (1 + np.exp(0.5)), 1 / (1 + np.exp(-1.0))], rtol=1e-6
    )
    np.testing.assert_allclose(det.boxes[0], [24, 16, 72, 48])
    np.testing.assert_allclose(cxcywh_to_xyxy(np.array([[0.25, 0.25, 0.2, 0.2]]), (64, 96)), [[14.4, 9.6, 33.6, 22.4]])
    strict = select_detections(logits, boxes, ids, lambda i: VOCAB[i], (64, 96), box_threshold=0.9)
    assert strict.phrases == ["red sofa"]
    # text threshold 0.9: only "sofa" (0.95) of query 0 stays in its phrase
    assert select_detections(logits, boxes, ids, lambda i: VOCAB[i], (64, 96), text_threshold=0.9).phrases[0] == "sofa"


def test_grounded_probe_end_to_end(grounded_files):
    from r360gpu.probes.grounded import GroundedSamProbe

    probe = GroundedSamProbe(*grounded_files)
    assert probe.name == "grounded-sam"
    calls = record(probe.dino.model)
    image = np.zeros((64, 96, 3), np.uint8)
    [pred] = probe.predict([ProbeView("v0", image, "post")], "Red sofa")
    feed = calls[0]
    assert feed["img"].shape == (1, 3, 800, 1200)  # shorter side 800, 1200 <= 1333
    assert feed["input_ids"].tolist() == [[2, 6, 7, 4, 3]] and feed["attention_mask"].dtype == bool
    assert feed["position_ids"].tolist() == [[0, 0, 1, 2, 0]]
    assert pred.count == 1 and pred.labels == ["red sofa"] and pred.probe == "grounded-sam"
    assert pred.scores[0] == pytest.approx(1 / (1 + np.exp(-3.0)))
    expect = np.zeros((64, 96), bool)
    expect[16:48, 24:72] = True  # box [24, 16, 72, 48]
    assert _iou(pred.masks[0], expect) > 0.9
    np.testing.assert_array_equal(pred.union(), pred.masks[0])

    # without phrase matching every box over the threshold becomes an instance
    from r360gpu.probes.grounded import GroundingParams

    loose = GroundedSamProbe(*grounded_files, params=GroundingParams(phrase_match=False))
    [all_pred] = loose.predict([ProbeView("v0", image, "post")], "red sofa")
    assert all_pred.labels == ["red sofa", "sofa", "red [SEP]"]
    assert loose.describe()["params"] != probe.describe()["params"]
    # nothing over the box threshold: an empty prediction of the view's size
    strict = GroundedSamProbe(*grounded_files, params=GroundingParams(box_threshold=0.99))
    [none] = strict.predict([ProbeView("v1", image, "post")], "red sofa")
    assert none.count == 0 and none.size == (64, 96)


def test_grounded_probe_describe(grounded_files):
    from r360gpu.probes.grounded import GroundedSamProbe

    desc = GroundedSamProbe(*grounded_files).describe()
    assert desc["kind"] == "semantic"
    assert desc["params"]["dino_image_resize"].startswith("PIL bilinear on the uint8 image")
    assert set(desc["models"]) == {
        "dino:groundingdino.onnx",
        "tokenizer:tokenizer.json",
        "sam-encoder:sam.encoder.onnx",
        "sam-decoder:sam.decoder.onnx",
    }
    g = desc["params"]["grounding"]
    assert (g["box_threshold"], g["text_threshold"], g["size"], g["max_size"]) == (0.35, 0.25, 800, 1333)


def test_grounded_fixed_input_size_and_sam2_boxes(tmp_path, tokenizer_json):
    from r360gpu.probes.grounded import GroundedSamProbe

    logits, boxes = _dino_outputs()
    dino = dino_model(tmp_path / "dino_static.onnx", logits, boxes, image_shape=(1, 3, 48, 64))
    # SAM2 box decoder: three multimask tokens; the best predicted IoU (token 1) is the box
    dec = sam2_decoder(tmp_path / "d2.onnx", iou=[0.5, 0.9, 0.7], shape="box", slope=[1, 1, 1], offset=[-1e4, 0, -1e4])
    probe = GroundedSamProbe(dino, tokenizer_json, sam2_encoder(tmp_path / "e2.onnx"), dec)
    assert probe.name == "grounded-sam2" and probe.dino.fixed_input == (48, 64)
    calls = record(probe.dino.model)
    [pred] = probe.predict([ProbeView("v0", np.zeros((64, 96, 3), np.uint8))], "red sofa")
    assert calls[0]["img"].shape == (1, 3, 48, 64)
    expect = np.zeros((64, 96), bool)
    expect[16:48, 24:72] = True
    assert pred.count == 1 and _iou(pred.masks[0], expect) > 0.9


def test_grounded_rejects_wrong_dino_signature(tmp_path, tokenizer_json, sam_pair):
    from r360gpu.probes.grounded import GroundedSamProbe

    bad = save_model(
        tmp_path / "notdino.onnx",
        [helper.make_node("Identity", ["img"], ["logits"])],
        [value_info("img", F, [1, 3, 8, 8])],
        [value_info("logits", F, [1, 3, 8, 8])],
    )
    with pytest.raises(InputError, match="GroundingDINO") as err:
        GroundedSamProbe(bad, tokenizer_json, *sam_pair)
    assert "img float[1, 3, 8, 8]" in str(err.value)


def test_tokenizer_errors(tmp_path):
    pytest.importorskip("tokenizers")
    from r360gpu.probes.grounded import DinoTokenizer

    with pytest.raises(InputError, match="does not exist"):
        DinoTokenizer(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(InputError, match="bad.json"):
        DinoTokenizer(bad)


def test_missing_tokenizers_package_is_a_clear_error(monkeypatch, tokenizer_json):
    import builtins

    from r360gpu.errors import R360Error
    from r360gpu.probes.grounded import DinoTokenizer

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "tokenizers":
            raise ImportError("no tokenizers")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(R360Error, match="pip install"):
        DinoTokenizer(tokenizer_json)


def test_no_warnings_on_clean_run(sam_pair):
    models = SamModels(*sam_pair)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        generate_masks(models, np.zeros((16, 16, 3), np.uint8), AmgParams(points_per_side=1))


def test_tokenizer_from_vocab_txt_matches_tokenizer_json(tmp_path, tokenizer_json):
    from r360gpu.probes.grounded import DinoTokenizer, GroundedSamProbe

    vocab = tmp_path / "vocab.txt"
    vocab.write_text("\n".join(VOCAB) + "\n", encoding="utf-8")
    from_json, from_txt = DinoTokenizer(tokenizer_json), DinoTokenizer(vocab)
    assert (from_json.format, from_txt.format) == ("tokenizer.json", "vocab.txt")
    for caption in ("red sofa .", "Red Sofas .", "the chair ? red sofa .", "unknown word ."):
        assert from_txt.encode(caption).tolist() == from_json.encode(caption).tolist()
    assert from_txt.encode("red sofas .").tolist() == [2, 6, 7, 10, 4, 3]
    assert from_txt.special_ids == from_json.special_ids == [2, 3, 4, 5]
    assert from_txt.id_to_token(7) == "sofa" and from_txt.id_to_token(999) == "[UNK]"
    bad = tmp_path / "broken.json"
    bad.write_text("{ not json", encoding="utf-8")
    with pytest.raises(InputError, match="tokenizer.json or a BERT vocab.txt"):
        DinoTokenizer(bad)


def test_grounded_resize_policies(tmp_path, grounded_files):
    from r360gpu.probes.grounded import GroundedSamProbe, GroundingParams

    image = np.zeros((64, 96, 3), np.uint8)
    shapes = {}
    for resize in (None, "800/1333", "600/700", "1200x800", "1200X800"):
        probe = GroundedSamProbe(*grounded_files, params=GroundingParams(resize=resize))
        calls = record(probe.dino.model)
        [pred] = probe.predict([ProbeView("v0", image, "post")], "red sofa")
        shapes[resize] = calls[0]["img"].shape[2:]
        expect = np.zeros((64, 96), bool)
        expect[16:48, 24:72] = True  # boxes are normalised to the image whatever the resize
        assert pred.count == 1 and _iou(pred.masks[0], expect) > 0.9
    assert shapes[None] == shapes["800/1333"] == (800, 1200)
    # 96 / 64 * 600 > 700: shorter side round(700 * 64 / 96) = 467, longer int(467 * 96 / 64) = 700
    assert shapes["600/700"] == (467, 700)
    assert shapes["1200x800"] == shapes["1200X800"] == (800, 1200)
    desc = GroundedSamProbe(*grounded_files, params=GroundingParams(resize="1200x800")).describe()["params"]
    assert desc["dino_input"] == "exactly 1200x800 (W x H)" and desc["grounding"]["resize"] == "1200x800"
    for bad in ("800", "0x800", "1333/800", "big", "800x"):
        with pytest.raises(InputError, match="resize"):
            GroundingParams(resize=bad)


def test_grounded_fixed_resize_must_match_a_fixed_graph(tmp_path, tokenizer_json, sam_pair):
    from r360gpu.probes.grounded import GroundingDino, GroundingParams

    logits, boxes = _dino_outputs()
    dino = dino_model(tmp_path / "dino_static.onnx", logits, boxes, image_shape=(1, 3, 48, 64))
    assert GroundingDino(dino, tokenizer_json, params=GroundingParams(resize="64x48")).input_shape(10, 10) == (48, 64)
    with pytest.raises(InputError, match="takes exactly 64x48"):
        GroundingDino(dino, tokenizer_json, params=GroundingParams(resize="1200x800"))


def test_grounded_spec_resize_and_vocab(tmp_path, grounded_files):
    from r360gpu.probes.registry import parse_probe_spec

    dino, _, enc, dec = grounded_files
    vocab = tmp_path / "vocab.txt"
    vocab.write_text("\n".join(VOCAB) + "\n", encoding="utf-8")
    probe = parse_probe_spec(f"grounded:dino={dino},tokenizer={vocab},sam-encoder={enc},sam-decoder={dec},resize=1200x800")
    assert probe.dino.tokenizer.format == "vocab.txt" and probe.grounding.resize_policy() == ("fixed", 800, 1200)
    with pytest.raises(InputError, match="resize"):
        parse_probe_spec(f"grounded:dino={dino},tokenizer={vocab},sam-encoder={enc},sam-decoder={dec},resize=huge")


# ============================================================ work on outputs nobody reads / shared encodings


def test_sam_decoder_pruned_to_the_outputs_read(sam_pair):
    import pickle

    from r360gpu.probes.onnx_models import pruned_model_bytes

    full = OnnxModel(sam_pair[1], role="SAM prompt decoder")
    assert set(full.outputs) == {"masks", "iou_predictions", "low_res_masks"}
    models = SamModels(*sam_pair)
    # The 'masks' branch (Resize to orig_im_size) is cut: the session only has what the AMG reads.
    assert set(models.decoder.outputs) == {"iou_predictions", "low_res_masks"}
    assert set(pickle.loads(pickle.dumps(models.decoder)).outputs) == {"iou_predictions", "low_res_masks"}
    emb = models.embed(np.zeros((40, 60, 3), np.uint8))
    points = np.array([[10.0, 20.0], [55.0, 3.0]])
    pruned = models.predict_points(emb, points)
    models.decoder = full
    whole = models.predict_points(emb, points)
    np.testing.assert_array_equal(pruned.logits, whole.logits)
    np.testing.assert_array_equal(pruned.iou, whole.iou)
    # Nothing to cut, or an output the model lacks: the file is used as it is.
    assert pruned_model_bytes(sam_pair[1], ("masks", "iou_predictions", "low_res_masks")) is None
    assert pruned_model_bytes(sam_pair[1], ("iou_predictions", "no_such_output")) is None


def test_pruning_keeps_what_subgraphs_read(tmp_path):
    from r360gpu.probes.onnx_models import pruned_model_bytes

    # y = If(cond, then: x + k, else: x - k); z = x * 2 is not read.  k is read only inside the branches.
    then_g = helper.make_graph([helper.make_node("Add", ["x", "k"], ["t"])], "then", [], [value_info("t", F, [3])])
    else_g = helper.make_graph([helper.make_node("Sub", ["x", "k"], ["e"])], "else", [], [value_info("e", F, [3])])
    nodes = [
        helper.make_node("Identity", ["k0"], ["k"]),
        helper.make_node("If", ["cond"], ["y"], then_branch=then_g, else_branch=else_g),
        helper.make_node("Mul", ["x", "two"], ["z"]),
    ]
    path = save_model(
        tmp_path / "if.onnx",
        nodes,
        [value_info("x", F, [3]), value_info("cond", onnx.TensorProto.BOOL, [])],
        [value_info("y", F, [3]), value_info("z", F, [3])],
        [const("k0", [1.0, 2.0, 3.0]), const("two", 2.0)],
    )
    cut = onnx.load_from_string(pruned_model_bytes(path, ("y",)))
    assert [n.op_type for n in cut.graph.node] == ["Identity", "If"]
    assert [t.name for t in cut.graph.initializer] == ["k0"]
    model = OnnxModel(path, outputs_read=("y",))
    assert list(model.outputs) == ["y"]
    x = np.array([1.0, 1.0, 1.0], np.float32)
    np.testing.assert_array_equal(model.run({"x": x, "cond": np.array(True)})["y"], [2.0, 3.0, 4.0])
    np.testing.assert_array_equal(model.run({"x": x, "cond": np.array(False)})["y"], [0.0, -1.0, -2.0])


def test_embedding_shared_by_models_on_the_same_encoder(tmp_path, sam_pair):
    from r360gpu.probes.onnx_models import EMBEDDINGS

    first, second = SamModels(*sam_pair), SamModels(*sam_pair)
    runs_first, runs_second = record(first.encoder), record(second.encoder)
    image = np.random.default_rng(1).integers(0, 256, (30, 40, 3), dtype=np.uint8)
    a = first.embed(image)
    b = second.embed(image)
    assert len(runs_first) == 1 and len(runs_second) == 0 and b is a
    assert second.embed(image / 255.0) is a  # the same pixels as float 0..1: the same encoder input
    other = image.copy()
    other[0, 0, 0] ^= 1
    second.embed(other)  # one pixel changed: encoded again
    assert len(runs_second) == 1
    # Another encoder file (even with the same content) is another model.
    copy = tmp_path / "copy.encoder.onnx"
    copy.write_bytes(sam_pair[0].read_bytes())
    third = SamModels(copy, sam_pair[1])
    runs_third = record(third.encoder)
    third.embed(image)
    assert len(runs_third) == 1
    np.testing.assert_array_equal(third.embed(image).features["image_embeddings"], a.features["image_embeddings"])
    EMBEDDINGS.clear()
