"""Boundary-sweep erosion / dilation on packed rows against cv2.erode / cv2.dilate."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.kernels import mask_iou as K
from r360gpu.kernels.morph import half_widths, perturb_packed, perturb_reference
from r360gpu.metrics.sensitivity import BOUNDARY_OFFSETS, boundary_targets, perturb_mask

OFFS = (-15, -10, -5, -1, 0, 1, 2, 5, 10, 15)


def _check(m, offs=OFFS):
    out = perturb_packed(m, offs)
    assert out.shape == (len(offs), m.shape[0], K.row_words(m.shape[1])) and out.dtype == np.uint32
    np.testing.assert_array_equal(out, K.pack_bits(np.stack([perturb_reference(m, o) for o in offs])))


@pytest.mark.parametrize("shape", [(1, 1), (1, 70), (70, 1), (3, 5), (37, 70), (64, 64), (100, 129), (31, 200), (40, 65)])
@pytest.mark.parametrize("density", [0.02, 0.5, 0.97])
def test_random_masks_equal_cv2(shape, density):
    rng = np.random.default_rng(abs(hash((shape, density))) % 2**32)
    _check(rng.random(shape) < density)


def test_adversarial_masks_equal_cv2():
    h, w = 45, 131  # odd, straddles 32- and 64-bit words
    empty = np.zeros((h, w), bool)
    _check(empty)
    _check(~empty)  # full: erosion keeps it full (outside counts as target)
    for y, x in [(0, 0), (h - 1, w - 1), (22, 63), (22, 64), (0, w - 1), (h - 1, 0)]:
        one = empty.copy()
        one[y, x] = True
        _check(one)
        _check(~one)  # one hole
    border = empty.copy()
    border[:, :3] = True  # touches the left border: not eroded from that side
    _check(border)
    stripe = empty.copy()
    stripe[10:12, :] = True
    _check(stripe)


def test_blob_like_masks_equal_cv2():
    rng = np.random.default_rng(7)
    import cv2

    m = np.zeros((120, 333), np.uint8)
    for _ in range(5):
        cv2.circle(m, (int(rng.integers(0, 333)), int(rng.integers(0, 120))), int(rng.integers(2, 40)), 1, -1)
    _check(m.astype(bool), BOUNDARY_OFFSETS)


def test_elliptical_rows_are_centred_runs():
    for r in range(1, 21):
        hw = half_widths(r)
        assert len(hw) == 2 * r + 1 and hw[r] == r and hw == hw[::-1]


def test_perturb_mask_and_bad_offsets():
    rng = np.random.default_rng(1)
    m = rng.random((30, 40)) < 0.4
    np.testing.assert_array_equal(perturb_mask(m, -5), perturb_reference(m, -5))
    with pytest.raises(InputError):
        perturb_mask(m, 2.5)
    with pytest.raises(InputError):
        perturb_packed(np.zeros(5, bool), [1])


def test_boundary_targets_areas_and_memo(ctx):
    rng = np.random.default_rng(2)
    m = rng.random((50, 70)) < 0.3
    bt = boundary_targets(m, ctx=ctx)
    ref = np.stack([perturb_reference(m, o) for o in BOUNDARY_OFFSETS])
    np.testing.assert_array_equal(bt.areas, ref.reshape(len(ref), -1).sum(1))
    np.testing.assert_array_equal(K.to_host(bt.packed, ctx=ctx), K.pack_bits(ref))
    assert boundary_targets(m.copy(), ctx=ctx) is bt  # same content: shared across methods
    assert boundary_targets(~m, ctx=ctx) is not bt


def test_boundary_targets_beyond_one_binding(small_ctx):
    rng = np.random.default_rng(3)
    m = rng.random((90, 200)) < 0.5  # 7 x 90 x 7 words: several chunks at 4 KiB
    bt = boundary_targets(m, ctx=small_ctx)
    assert len(K.device_chunks(bt.packed, small_ctx)) > 1  # uploaded now on the host-path (CPU adapter) default
    ref = np.stack([perturb_reference(m, o) for o in BOUNDARY_OFFSETS])
    np.testing.assert_array_equal(K.to_host(bt.packed, ctx=small_ctx), K.pack_bits(ref))
