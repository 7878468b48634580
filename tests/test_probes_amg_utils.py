"""Pure-numpy parts of the model probes: SAM's automatic-mask-generator helpers
(grid, crops, stability, boxes, NMS, small regions) and the image pre- and
post-processing, checked against hand-computed values (and PIL / a direct
bilinear formula where those define the convention)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes import amg_utils as au
from r360gpu.probes import preprocess as pp

# ---------------------------------------------------------------- point grid


def test_point_grid_cell_centres_row_major():
    g = au.build_point_grid(2)
    np.testing.assert_allclose(g, [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]])
    g32 = au.build_point_grid(32)
    assert g32.shape == (1024, 2)
    assert g32[0].tolist() == [1 / 64, 1 / 64]
    assert g32[1, 0] == pytest.approx(3 / 64) and g32[1, 1] == pytest.approx(1 / 64)
    assert g32[-1].tolist() == pytest.approx([63 / 64, 63 / 64])


def test_point_grid_rejects_zero():
    with pytest.raises(ValueError):
        au.build_point_grid(0)


def test_layer_grids_downscale():
    grids = au.build_all_layer_point_grids(32, 2, 2)
    assert [len(g) for g in grids] == [32 * 32, 16 * 16, 8 * 8]
    assert [len(g) for g in au.build_all_layer_point_grids(5, 1, 2)] == [25, 4]


# ---------------------------------------------------------------- crops


def test_crop_boxes_layer0_is_whole_image():
    boxes, layers = au.generate_crop_boxes((30, 40), 0, 512 / 1500)
    assert boxes == [[0, 0, 40, 30]] and layers == [0]


def test_crop_boxes_one_layer_hand_computed():
    # 100 x 200 (h x w): overlap = int(512/1500 * 100 * 2/2) = 34;
    # crop_w = ceil((34 + 200) / 2) = 117, crop_h = ceil((34 + 100) / 2) = 67;
    # x0 = 0, 83; y0 = 0, 33; x0 outer loop.
    boxes, layers = au.generate_crop_boxes((100, 200), 1, 512 / 1500)
    assert layers == [0, 1, 1, 1, 1]
    assert boxes == [
        [0, 0, 200, 100],
        [0, 0, 117, 67],
        [0, 33, 117, 100],
        [83, 0, 200, 67],
        [83, 33, 200, 100],
    ]


def test_crop_boxes_two_layers_count_and_bounds():
    boxes, layers = au.generate_crop_boxes((64, 64), 2, 512 / 1500)
    assert layers.count(1) == 4 and layers.count(2) == 16
    for x0, y0, x1, y1 in boxes:
        assert 0 <= x0 < x1 <= 64 and 0 <= y0 < y1 <= 64
    # layer 2: overlap int(0.3413 * 64 * 0.5) = 10, crop = ceil((30 + 64) / 4) = 24, step 14
    assert [b for b, layer in zip(boxes, layers) if layer == 2][:4] == [
        [0, 0, 24, 24],
        [0, 14, 24, 38],
        [0, 28, 24, 52],
        [0, 42, 24, 64],
    ]


# ---------------------------------------------------------------- stability


def test_stability_score_hand_computed():
    logits = np.array(
        [
            [[2.5, 0.5, -0.5], [-2.0, 1.5, 0.9]],  # > +1: 2.5, 1.5 -> 2; > -1: all but -2.0 -> 5
            [[-3.0, -3.0, -3.0], [-3.0, -3.0, -3.0]],  # empty even at the low threshold
            [[5.0, 5.0, -5.0], [-5.0, -5.0, -5.0]],  # perfectly stable
        ],
        np.float32,
    )
    s = au.stability_score(logits, 0.0, 1.0)
    assert s.dtype == np.float32
    np.testing.assert_allclose(s, [2 / 5, 0.0, 1.0])
    # thresholds are strict: a logit exactly at t + offset does not count
    assert au.stability_score(np.array([[[1.0, 0.5]]]), 0.0, 1.0)[0] == 0.0
    # mask_threshold shifts both thresholds
    assert au.stability_score(logits[:1], 1.0, 1.0)[0] == pytest.approx(1 / 4)  # >2: 2.5; >0: 2.5, 0.5, 1.5, 0.9


def test_stability_score_empty_batch():
    assert au.stability_score(np.zeros((0, 4, 4)), 0.0, 1.0).shape == (0,)


# ---------------------------------------------------------------- boxes


def test_masks_to_boxes_inclusive_and_empty():
    m = np.zeros((3, 5, 6), bool)
    m[0, 1:3, 2:5] = True  # rows 1..2, cols 2..4
    m[1, 4, 0] = True
    boxes = au.masks_to_boxes(m)
    assert boxes.dtype == np.int64
    assert boxes.tolist() == [[2, 1, 4, 2], [0, 4, 0, 4], [0, 0, 0, 0]]
    assert au.masks_to_boxes(np.zeros((0, 5, 6), bool)).shape == (0, 4)


def test_box_area_and_iou_torchvision_convention():
    a = np.array([[0, 0, 10, 10], [5, 5, 15, 15], [3, 3, 3, 3]], float)
    assert au.box_area(a).tolist() == [100, 100, 0]
    iou = au.box_iou(a, a)
    assert iou[0, 1] == pytest.approx(25 / 175)
    assert iou[0, 0] == 1.0
    assert iou[2, 2] == 0.0  # zero union: 0, never NaN
    assert not np.isnan(iou).any()


def test_nms_greedy_strictly_greater_and_order():
    boxes = np.array([[0, 0, 10, 10], [1, 0, 11, 10], [20, 20, 30, 30], [0, 0, 10, 10]], float)
    scores = np.array([0.5, 0.9, 0.3, 0.7])
    # visit order 1 (0.9), 3 (0.7), 0 (0.5), 2 (0.3); IoU(1,3) = IoU(1,0) = 90/110
    assert au.nms(boxes, scores, 0.7).tolist() == [1, 2]
    assert au.nms(boxes, scores, 0.95).tolist() == [1, 3, 2]  # 3 and 0 coincide: IoU 1 > 0.95
    # IoU exactly at the threshold is kept
    two = np.array([[0, 0, 10, 10], [0, 0, 10, 5]], float)  # IoU 0.5
    assert au.nms(two, np.array([1.0, 0.5]), 0.5).tolist() == [0, 1]
    assert au.nms(two, np.array([1.0, 0.5]), 0.49).tolist() == [0]


def test_nms_ties_keep_lower_index_first():
    boxes = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [0, 0, 10, 10]], float)
    assert au.nms(boxes, np.array([1.0, 1.0, 1.0]), 0.7).tolist() == [0]
    assert au.nms(boxes, np.array([0.0, 1.0, 1.0]), 0.7).tolist() == [1]
    assert au.nms(np.zeros((0, 4)), np.zeros(0), 0.7).tolist() == []


def test_nms_degenerate_boxes_never_suppress():
    # one-pixel masks have zero-area boxes: IoU is 0 (torchvision: NaN), so both stay
    boxes = np.array([[4, 4, 4, 4], [4, 4, 4, 4]], float)
    assert au.nms(boxes, np.array([0.9, 0.8]), 0.7).tolist() == [0, 1]


def test_box_near_crop_edge():
    crop = [10, 20, 60, 80]
    orig = [0, 0, 60, 100]
    boxes = np.array(
        [
            # uncropped (15, 20, 40, 50): each coordinate near a crop edge is as near the image edge
            [5, 0, 30, 30],
            [25, 25, 30, 30],  # uncropped (35, 45, 40, 50): 25, 25, 20 (image 20), 30 from the crop edges
            [25, 25, 30, 45],  # y1 + 20 = 65: 15 from crop y1 = 80, 35 from image y1 = 100 -> near
            [25, 25, 45, 30],  # x1 + 10 = 55, near crop x1 60, but also near image x1 60 -> not
        ],
        float,
    )
    assert au.is_box_near_crop_edge(boxes, crop, orig).tolist() == [False, False, True, False]
    # tolerance is inclusive: exactly 20 away counts as near
    assert au.is_box_near_crop_edge(np.array([[5, 5, 6, 40]], float), crop, orig).tolist() == [True]
    # the whole-image crop never filters
    assert not au.is_box_near_crop_edge(np.array([[0, 0, 59, 99]], float), orig, orig).any()


def test_uncrop():
    crop = [3, 5, 7, 9]
    assert au.uncrop_boxes(np.array([[0, 0, 1, 2]]), crop).tolist() == [[3, 5, 4, 7]]
    assert au.uncrop_points(np.array([[0.5, 1.0]]), crop).tolist() == [[3.5, 6.0]]
    m = np.ones((1, 4, 4), bool)
    full = au.uncrop_masks(m, crop, 10, 8)
    assert full.shape == (1, 10, 8)
    assert full[0, 5:9, 3:7].all() and full.sum() == 16
    assert au.uncrop_masks(m, [0, 0, 4, 4], 4, 4) is m


# ---------------------------------------------------------------- small regions


def test_remove_small_regions_holes():
    mask = np.zeros((12, 12), bool)
    mask[2:10, 2:10] = True
    mask[4:6, 4:6] = False  # 4-pixel hole
    filled, changed = au.remove_small_regions(mask, 5, "holes")
    assert changed and filled[2:10, 2:10].all() and filled.sum() == 64
    same, changed = au.remove_small_regions(mask, 4, "holes")  # 4 is not < 4
    assert not changed and same is mask


def test_remove_small_regions_border_background_counts_as_hole():
    # the outside is one background region too: small enough, SAM fills it
    mask = np.ones((6, 6), bool)
    mask[0, 0] = False
    filled, changed = au.remove_small_regions(mask, 2, "holes")
    assert changed and filled.all()


def test_remove_small_regions_islands():
    mask = np.zeros((12, 12), bool)
    mask[1:6, 1:6] = True  # 25 px
    mask[9, 9] = True  # 1 px
    mask[10, 10] = True  # diagonal neighbour: 8-connected, so one 2-px island
    kept, changed = au.remove_small_regions(mask, 3, "islands")
    assert changed and kept.sum() == 25 and not kept[9, 9]
    # every island small: the largest stays
    kept, changed = au.remove_small_regions(mask, 100, "islands")
    assert changed and kept.sum() == 25
    with pytest.raises(ValueError):
        au.remove_small_regions(mask, 3, "both")


# ---------------------------------------------------------------- image conversion


def test_as_rgb01_accepts_uint8_and_float():
    u8 = np.array([[[0, 51, 255]]], np.uint8)
    np.testing.assert_allclose(pp.as_rgb01(u8), [[[0.0, 0.2, 1.0]]], atol=1e-7)
    f = np.array([[[-0.01, 0.5, 1.02]]], np.float64)
    out = pp.as_rgb01(f)
    assert out.dtype == np.float32 and out.tolist() == [[[0.0, 0.5, 1.0]]]


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((4, 4), np.uint8),
        np.zeros((4, 4, 4), np.uint8),
        np.zeros((4, 4, 3), np.uint16),
        np.full((2, 2, 3), np.nan),
    ],
)
def test_as_rgb01_rejects(bad):
    with pytest.raises(InputError):
        pp.as_rgb01(bad)


# ---------------------------------------------------------------- resizing


def test_resize_antialias_hand_computed_downscale():
    # 4 -> 2 (scale 2, support 2): output 0 centre 1.0 in input pixels, window
    # [int(-0.5), int(3.5)) = [0, 3): weights 1 - |j + 0.5 - 1| / 2 = 0.75, 0.75, 0.25
    row = np.array([[0.0, 4.0, 8.0, 16.0]], np.float32)
    out = pp.resize_antialias(row, (1, 2))
    w = np.array([0.75, 0.75, 0.25])
    expect0 = (w * [0, 4, 8]).sum() / w.sum()
    # output 1 centre 3.0: window [int(1.5), min(int(5.5), 4)) = [1, 4): 0.25, 0.75, 0.75
    expect1 = (np.array([0.25, 0.75, 0.75]) * [4, 8, 16]).sum() / 1.75
    np.testing.assert_allclose(out[0], [expect0, expect1], rtol=1e-6)


def test_resize_antialias_hand_computed_upscale_is_bilinear():
    # 2 -> 4: plain bilinear, half-pixel centres, clamped edges
    out = pp.resize_antialias(np.array([[0.0, 8.0]], np.float32), (1, 4))
    np.testing.assert_allclose(out[0], [0.0, 2.0, 6.0, 8.0])


def test_resize_antialias_matches_pil_float():
    PIL = pytest.importorskip("PIL.Image")
    rng = np.random.default_rng(3)
    for h, w, oh, ow in [(40, 60, 17, 23), (9, 11, 30, 25), (50, 20, 50, 7)]:
        x = rng.random((h, w)).astype(np.float32)
        ref = np.asarray(PIL.fromarray(x, mode="F").resize((ow, oh), PIL.BILINEAR))
        np.testing.assert_allclose(pp.resize_antialias(x, (oh, ow)), ref, atol=1e-5)


def test_resize_antialias_channels_and_identity():
    x = np.random.default_rng(0).random((5, 7, 3)).astype(np.float32)
    out = pp.resize_antialias(x, (3, 4))
    assert out.shape == (3, 4, 3)
    for c in range(3):
        np.testing.assert_allclose(out[..., c], pp.resize_antialias(x[..., c], (3, 4)), rtol=1e-6)
    np.testing.assert_array_equal(pp.resize_antialias(x, (5, 7)), x)
    const = np.full((13, 17, 3), 0.3, np.float32)
    np.testing.assert_allclose(pp.resize_antialias(const, (1024, 700)), 0.3, rtol=1e-6)


def test_longest_side_shape_rounds_half_up():
    assert pp.longest_side_shape(480, 640, 1024) == (768, 1024)
    assert pp.longest_side_shape(33, 50, 1024) == (676, 1024)  # 33 * 20.48 = 675.84
    assert pp.longest_side_shape(1500, 2250, 1024) == (683, 1024)  # 682.67
    assert pp.longest_side_shape(2000, 10, 1024) == (1024, 5)  # 5.12


def test_sam_encoder_input_normalises_and_pads():
    colour = np.array([0.5, 0.25, 1.0], np.float32)
    image = np.broadcast_to(colour, (32, 64, 3)).copy()
    tensor, resized = pp.sam_encoder_input(image, 1024)
    assert tensor.shape == (1, 3, 1024, 1024) and tensor.dtype == np.float32
    assert resized == (512, 1024)
    # segment-anything takes uint8: 0.5 * 255 = 127.5 and 0.25 * 255 = 63.75 round to 128 and 64.
    expect = (np.array([128.0, 64.0, 255.0]) - np.array(pp.SAM_PIXEL_MEAN)) / np.array(pp.SAM_PIXEL_STD)
    for c in range(3):
        np.testing.assert_allclose(tensor[0, c, :512], expect[c], rtol=1e-5)
        assert not tensor[0, c, 512:].any()  # padding after normalisation is 0


def test_sam_resized_image_is_0_255_unpadded():
    image = np.full((20, 10, 3), 0.2, np.float32)
    out = pp.sam_resized_image(image, 1024)
    assert out.shape == (1024, 512, 3) and out.dtype == np.float32
    np.testing.assert_array_equal(out, 51.0)  # 0.2 * 255 = 51, a constant stays exact through PIL's resize


def test_sam2_encoder_input_plain_resize_imagenet():
    colour = np.array([0.1, 0.6, 0.9], np.float32)
    image = np.broadcast_to(colour, (30, 70, 3)).copy()
    tensor = pp.sam2_encoder_input(image, (1024, 1024))
    assert tensor.shape == (1, 3, 1024, 1024)
    expect = (colour - np.array(pp.IMAGENET_MEAN)) / np.array(pp.IMAGENET_STD)
    for c in range(3):
        np.testing.assert_allclose(tensor[0, c], expect[c], rtol=1e-5)


def test_dino_input_shape_hand_computed():
    assert pp.dino_input_shape(480, 640) == (800, 1066)  # 800 * 640 / 480 = 1066.7, truncated
    assert pp.dino_input_shape(640, 480) == (1066, 800)
    # 1200 / 400 * 800 = 2400 > 1333: shorter side round(1333 * 400 / 1200) = 444
    assert pp.dino_input_shape(400, 1200) == (444, 1332)
    assert pp.dino_input_shape(800, 900) == (800, 900)  # already there
    assert pp.dino_input_shape(100, 100, max_size=None) == (800, 800)


def test_dino_encoder_input():
    image = np.full((8, 12, 3), 0.485, np.float32)
    tensor = pp.dino_encoder_input(image, (16, 24))
    assert tensor.shape == (1, 3, 16, 24)
    # 0.485 * 255 = 123.675 -> uint8 124; ToTensor divides by 255 in float32.
    expect = (np.float32(124) / np.float32(255) - np.float32(0.485)) / np.float32(0.229)
    np.testing.assert_array_equal(tensor[0, 0], expect)


# ---------------------------------------------------------------- logit upsampling


def _bilinear_reference(x: np.ndarray, oh: int, ow: int) -> np.ndarray:
    """torch F.interpolate(bilinear, align_corners=False) written out."""

    def taps(n_in, n_out):
        src = np.maximum((np.arange(n_out) + 0.5) * (n_in / n_out) - 0.5, 0.0)
        i0 = np.minimum(np.floor(src).astype(int), n_in - 1)
        i1 = np.minimum(i0 + 1, n_in - 1)
        return i0, i1, src - i0

    r0, r1, ly = taps(x.shape[0], oh)
    c0, c1, lx = taps(x.shape[1], ow)
    top = x[r0][:, c0] * (1 - lx) + x[r0][:, c1] * lx
    bottom = x[r1][:, c0] * (1 - lx) + x[r1][:, c1] * lx
    return top * (1 - ly[:, None]) + bottom * ly[:, None]


def test_resize_logits_matches_torch_bilinear_formula():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((3, 16, 16)).astype(np.float32)
    for size in [(64, 64), (7, 11), (16, 16), (33, 8)]:
        out = pp.resize_logits(x, size)
        assert out.shape == (3,) + size
        for k in range(3):
            np.testing.assert_allclose(out[k], _bilinear_reference(x[k].astype(np.float64), *size), atol=1e-5)


def test_resize_logits_many_channels_and_one():
    x = np.random.default_rng(2).standard_normal((300, 4, 4)).astype(np.float32)
    out = pp.resize_logits(x, (8, 6))
    np.testing.assert_allclose(out[299], _bilinear_reference(x[299].astype(np.float64), 8, 6), atol=1e-5)
    one = pp.resize_logits(x[:1], (8, 6))
    assert one.shape == (1, 8, 6)


def test_sam_logits_to_image_crops_padding():
    # low-res logits: left half (in the padded 1024 frame) +5, right half -5;
    # image 512 x 256 -> resized 1024 x 512: the kept region is the left
    # half of the frame, so the whole image is positive except nothing
    low = np.where(np.arange(256)[None, :] < 128, 5.0, -5.0).astype(np.float32)
    low = np.broadcast_to(low, (1, 256, 256)).copy()
    out = pp.sam_logits_to_image(low, 1024, (1024, 512), (512, 256))
    assert out.shape == (1, 512, 256)
    assert (out[0, :, :-2] > 0).all()
    # without the crop the right half of the image would be negative
    wrong = pp.resize_logits(low, (512, 256))
    assert (wrong[0, :, 200:] < 0).all()


def test_sam_logits_linear_ramp_hand_computed():
    # a ramp linear in x survives bilinear resampling exactly away from the clamped border
    xs = (4 * np.arange(256) + 1.5).astype(np.float32)  # low-res pixel centres in the 1024 frame
    low = np.broadcast_to(xs, (1, 256, 256)).copy()
    out = pp.sam_logits_to_image(low, 1024, (1024, 1024), (64, 64))
    centres = (np.arange(64) + 0.5) * 16 - 0.5  # image pixel centres in the 1024 frame
    np.testing.assert_allclose(out[0, 10, 2:-2], centres[2:-2], rtol=1e-5)
    assert math.isclose(float(out[0, 0, 0]), float(out[0, 63, 0]))


def test_nms_iou_in_float32_like_torchvision():
    # IoU exactly 3/10: torchvision computes 0.3f = 0.30000001 > 0.3 and suppresses;
    # a float64 IoU (0.3, not > 0.3) would keep both boxes.
    boxes = np.array([[16, 32, 49, 56], [26, 32, 41, 46], [24, 36, 54, 42]], np.float64)
    iou = au.box_iou(boxes[1:2], boxes[2:3])[0, 0]
    assert iou == pytest.approx(0.3, abs=1e-12)
    keep = au.nms(boxes[1:], np.array([0.9, 0.8]), 0.3)
    assert keep.tolist() == [0]
    assert au.nms(boxes[1:], np.array([0.9, 0.8]), 0.31).tolist() == [0, 1]
    # zero-area boxes: 0/0 IoU never suppresses
    flat = np.array([[5, 5, 5, 9], [5, 5, 5, 9]], np.float64)
    assert au.nms(flat, np.array([1.0, 1.0]), 0.0).tolist() == [0, 1]
