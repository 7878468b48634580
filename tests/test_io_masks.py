"""Target mask loading."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.masks import load_mask


def _png(path, img):
    assert cv2.imwrite(str(path), img)
    return path


def test_grey_mask_any_nonzero_is_target(tmp_path):
    img = np.zeros((4, 6), np.uint8)
    img[1, 2], img[3, 5] = 1, 255
    m = load_mask(_png(tmp_path / "m.png", img))
    assert m.dtype == bool and m.shape == (4, 6)
    assert m.sum() == 2 and m[1, 2] and m[3, 5]


def test_colour_and_16_bit_masks(tmp_path):
    rgb = np.zeros((3, 3, 3), np.uint8)
    rgb[0, 0, 2] = 7  # only one channel non-zero
    assert load_mask(_png(tmp_path / "c.png", rgb)).sum() == 1
    deep = np.zeros((2, 2), np.uint16)
    deep[1, 1] = 256  # low byte zero, still non-zero
    assert load_mask(_png(tmp_path / "d.png", deep)).tolist() == [[False, False], [False, True]]


def test_alpha_channel_is_ignored(tmp_path):
    rgba = np.zeros((2, 3, 4), np.uint8)
    rgba[..., 3] = 255  # opaque everywhere
    rgba[0, 1, 1] = 9
    m = load_mask(_png(tmp_path / "a.png", rgba))
    assert m.sum() == 1 and m[0, 1]


def test_resize_with_warning_and_aspect_mismatch(tmp_path):
    img = np.zeros((4, 8), np.uint8)
    img[:2, :4] = 255  # top-left quarter
    p = _png(tmp_path / "m.png", img)
    with pytest.warns(R360Warning, match="8x4, resized to the view's 16x8"):
        m = load_mask(p, shape=(8, 16))
    assert m.shape == (8, 16) and m[:4, :8].all() and not m[4:].any() and not m[:, 8:].any()
    assert load_mask(p, shape=(4, 8)).sum() == 8
    with pytest.raises(InputError, match="different aspect ratio"):
        load_mask(p, shape=(8, 8))


def test_unreadable_files(tmp_path):
    (tmp_path / "t.png").write_text("not an image")
    with pytest.raises(InputError, match="t.png: cannot decode mask"):
        load_mask(tmp_path / "t.png")
    (tmp_path / "e.png").write_bytes(b"")
    with pytest.raises(InputError, match="cannot decode"):
        load_mask(tmp_path / "e.png")
    with pytest.raises(InputError, match="cannot read mask"):
        load_mask(tmp_path / "missing.png")
    with pytest.raises(InputError, match="cannot read mask"):
        load_mask(tmp_path)


@pytest.mark.parametrize("channels", [3, 4])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_colour_planes_any_nonzero_random(tmp_path, channels, dtype):
    """Random colour masks: a pixel is target exactly when one of its colour channels is non-zero
    (the alpha channel of an RGBA mask with some colour is not read); one non-zero value per pixel
    in a random channel catches a channel left out."""
    rng = np.random.default_rng(channels * 10 + np.dtype(dtype).itemsize)
    img = np.zeros((37, 53, channels), dtype)
    hit = rng.random((37, 53)) < 0.3
    which = rng.integers(0, 3, (37, 53))
    ys, xs = np.nonzero(hit)
    img[ys, xs, which[ys, xs]] = rng.integers(1, np.iinfo(dtype).max, ys.size, dtype=np.int64).astype(dtype)
    if channels == 4:
        img[..., 3] = rng.integers(0, 2, (37, 53)) * np.iinfo(dtype).max  # alpha: not the target
    m = load_mask(_png(tmp_path / "r.png", img))
    assert np.array_equal(m, hit)
