"""The uint8 resize of the SAM / GroundingDINO preprocessing against PIL, bit for bit.

segment-anything (``ResizeLongestSide.apply_image``) and GroundingDINO
(``T.RandomResize``) resize uint8 images with ``PIL.Image.resize(BILINEAR)``;
r360gpu re-does Pillow's 8-bit fixed-point arithmetic in numpy
(``preprocess.resize_uint8_pil``).  Pillow comes with matplotlib (a
dependency), so these run in CI; they are skipped where it is absent.
"""

from __future__ import annotations

import numpy as np
import pytest

from r360gpu.probes import preprocess as pp

Image = pytest.importorskip("PIL.Image")
PIL_VERSION = tuple(int(v) for v in __import__("PIL").__version__.split(".")[:2])
#: Pillow versions whose pass order r360gpu follows exactly (see resize_uint8_pil).
EXACT_ORDER = (12, 2) <= PIL_VERSION < (13, 0)


def _pil(img: np.ndarray, oh: int, ow: int) -> np.ndarray:
    return np.asarray(Image.fromarray(img).resize((ow, oh), Image.BILINEAR))


def _swapped(img: np.ndarray, oh: int, ow: int) -> np.ndarray:
    """The same passes in the other order than resize_uint8_pil's."""
    tall = img.shape[0] > img.shape[1] * 100 and oh < img.shape[0]
    axes = [(1, ow), (0, oh)] if tall else [(0, oh), (1, ow)]
    for axis, n in axes:
        if img.shape[axis] != n:
            img = pp._pil_pass(img, axis, n)
    return img


def _cases(rng, n):
    for trial in range(n):
        h, w = int(rng.integers(1, 200)), int(rng.integers(1, 200))
        oh, ow = int(rng.integers(1, 260)), int(rng.integers(1, 260))
        if trial % 7 == 3:  # over 100 times taller than wide
            h, w = int(rng.integers(101, 400)), 1
        if trial % 5 == 0:  # saturated: tests clip8 at both ends
            img = (rng.integers(0, 2, (h, w, 3)) * 255).astype(np.uint8)
        else:
            img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        yield img, oh, ow


def test_one_axis_resizes_equal_pil():
    """Only one pass: no pass order to choose, every Pillow version agrees."""
    rng = np.random.default_rng(0)
    for img, oh, ow in _cases(rng, 120):
        for shape in ((img.shape[0], ow), (oh, img.shape[1])):
            np.testing.assert_array_equal(pp.resize_uint8_pil(img, shape), _pil(img, *shape), err_msg=str(shape))


def test_two_axis_resizes_equal_pil():
    """Pillow 12.2 / 12.3 order the passes as r360gpu; other versions order some
    shapes the other way, and then the swapped passes give their pixels exactly."""
    rng = np.random.default_rng(1)
    swapped = 0
    for img, oh, ow in _cases(rng, 200):
        ref = _pil(img, oh, ow)
        out = pp.resize_uint8_pil(img, (oh, ow))
        if EXACT_ORDER or np.array_equal(out, ref):
            np.testing.assert_array_equal(out, ref, err_msg=f"{img.shape} -> {(oh, ow)}")
        else:
            swapped += 1
            np.testing.assert_array_equal(_swapped(img, oh, ow), ref, err_msg=f"{img.shape} -> {(oh, ow)}")
            assert np.abs(out.astype(int) - ref).max() <= 1
    assert swapped < 200


def test_sam_sizes_equal_pil():
    """The encoder-input shapes of common image sizes (longest side -> 1024)."""
    rng = np.random.default_rng(2)
    for h, w in ((480, 640), (1080, 1920), (1500, 2250), (300, 200), (1024, 1024), (7, 1000)):
        img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        shape = pp.longest_side_shape(h, w, 1024)
        ref = _pil(img, *shape)
        out = pp.resize_uint8_pil(img, shape)
        if not EXACT_ORDER and not np.array_equal(out, ref):
            ref = _swapped(img, *shape)  # see test_two_axis_resizes_equal_pil
        np.testing.assert_array_equal(out, ref, err_msg=str((h, w)))


def test_grey_and_single_channel():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (37, 53), dtype=np.uint8)
    np.testing.assert_array_equal(pp.resize_uint8_pil(img, (37, 20)), _pil(img, 37, 20))
    np.testing.assert_array_equal(pp.resize_uint8_pil(img, (90, 53)), _pil(img, 90, 53))


def test_identity_and_bad_input():
    img = np.arange(24, dtype=np.uint8).reshape(2, 4, 3)
    np.testing.assert_array_equal(pp.resize_uint8_pil(img, (2, 4)), img)
    with pytest.raises(ValueError, match="uint8"):
        pp.resize_uint8_pil(img.astype(np.float32), (3, 3))
    with pytest.raises(ValueError, match="positive"):
        pp.resize_uint8_pil(img, (0, 3))


def test_to_uint8_inverts_as_rgb01():
    u8 = np.arange(256, dtype=np.uint8).reshape(16, 16, 1).repeat(3, axis=2)
    np.testing.assert_array_equal(pp.to_uint8(pp.as_rgb01(u8)), u8)
    # Halves round up (floor(x + 0.5)), out-of-range floats clip.
    np.testing.assert_array_equal(pp.to_uint8(np.array([0.5 / 255, 1.5 / 255, -0.1, 1.2], np.float64)), [1, 2, 0, 255])


def test_sam_encoder_input_equals_segment_anything_recipe():
    """ResizeLongestSide.apply_image (PIL on uint8) then Sam.preprocess ((x - mean) / std in
    float32, zero padding), written out with PIL: equal bit for bit."""
    rng = np.random.default_rng(4)
    img = rng.integers(0, 256, (45, 70, 3), dtype=np.uint8)
    tensor, (nh, nw) = pp.sam_encoder_input(pp.as_rgb01(img), 256)
    assert (nh, nw) == (165, 256)
    resized = _pil(img, nh, nw)  # upscaling both sides: every Pillow runs the horizontal pass first
    x = (resized.astype(np.float32) - np.array(pp.SAM_PIXEL_MEAN, np.float32)) / np.array(pp.SAM_PIXEL_STD, np.float32)
    ref = np.zeros((1, 3, 256, 256), np.float32)
    ref[0, :, :nh, :nw] = x.transpose(2, 0, 1)
    np.testing.assert_array_equal(tensor, ref)


def test_dino_encoder_input_equals_groundingdino_recipe():
    """RandomResize (PIL on uint8), ToTensor (float32 / 255), Normalize: bit for bit."""
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (60, 90, 3), dtype=np.uint8)
    shape = (80, 120)
    tensor = pp.dino_encoder_input(pp.as_rgb01(img), shape)
    x = _pil(img, *shape).astype(np.float32) / np.float32(255)
    mean, std = np.array(pp.IMAGENET_MEAN, np.float32), np.array(pp.IMAGENET_STD, np.float32)
    np.testing.assert_array_equal(tensor, ((x - mean) / std).transpose(2, 0, 1)[None])
