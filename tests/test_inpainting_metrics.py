"""r360gpu.metrics.inpainting (float64) against a float32 numpy model of AuraFusion360's aura_eval.py
(tests/aura_eval_oracle.py) to 1e-4, on random and adversarial inputs; the mask readers against
PIL + to_tensor semantics; the default / compat mode differences."""
from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from r360gpu.errors import InputError
from r360gpu.io.inpaint_folders import natural_key, read_mask_binary, read_mask_script
from r360gpu.metrics import fidelity
from r360gpu.metrics.inpainting import (EMPTY_MASK, masked_psnr, masked_ssim, metric_mean, psnr_3dgs, score_view,
                                        script_weights, ssim_3dgs, summarise)
from tests import aura_eval_oracle as oracle

TOL = 1e-4


def _img(rng, h, w):
    return (rng.integers(0, 256, size=(h, w, 3)).astype(np.float32) / np.float32(255))


def _chw(a):
    return np.ascontiguousarray(a.transpose(2, 0, 1), dtype=np.float32)


def _close(ours, ref):
    if math.isnan(ref) or math.isinf(ref):
        assert ours == ref or (math.isnan(ours) and math.isnan(ref))
    else:
        assert abs(ours - ref) <= TOL, (ours, ref)


@pytest.mark.parametrize("h,w", [(32, 48), (13, 17), (11, 11), (3, 4), (1, 1), (40, 7)])
def test_full_image_metrics_match_the_script(h, w):
    rng = np.random.default_rng([h, w])
    a, b = _img(rng, h, w), _img(rng, h, w)
    _close(psnr_3dgs(a, b), oracle.psnr(_chw(a), _chw(b)))
    _close(ssim_3dgs(a, b), oracle.ssim(_chw(a), _chw(b)))
    # a near copy: high PSNR and SSIM near 1, where float32 rounding matters most
    c = np.clip(a + rng.normal(0, 0.002, a.shape).astype(np.float32), 0, 1)
    _close(psnr_3dgs(a, c), oracle.psnr(_chw(a), _chw(c)))
    _close(ssim_3dgs(a, c), oracle.ssim(_chw(a), _chw(c)))


def test_adversarial_images():
    z, o = np.zeros((16, 20, 3), np.float32), np.ones((16, 20, 3), np.float32)
    for a, b in [(z, o), (o, z), (z, z), (o, o)]:
        _close(psnr_3dgs(a, b), oracle.psnr(_chw(a), _chw(b)))
        _close(ssim_3dgs(a, b), oracle.ssim(_chw(a), _chw(b)))
    assert psnr_3dgs(z, z) == math.inf
    assert psnr_3dgs(z, o) == 0.0


def test_zero_padding_differs_from_valid_ssim():
    """The 3DGS SSIM sees black outside the image; fidelity.ssim keeps only inner windows."""
    rng = np.random.default_rng(1)
    a = _img(rng, 24, 24)
    b = (0.5 * a + 0.3).astype(np.float32)  # a contrast change: the black border weighs it differently
    assert abs(ssim_3dgs(a, b) - fidelity.ssim(a, b)) > 1e-2


def _masks(rng, h, w):
    frac = rng.integers(0, 256, size=(h, w)).astype(np.float32) / np.float32(255)  # many values in (0, 0.5]
    one = np.zeros((h, w), np.float32)
    one[h // 2, w // 3] = 1
    edge = np.zeros((h, w), np.float32)
    edge[0, 0] = 0.2  # a lone fractional corner pixel: counted by masked PSNR, weight 0.2 in masked SSIM
    far = np.zeros((h, w), np.float32)
    far[0, w - 1] = far[h - 1, 0] = 0.7  # two pixels at opposite corners: the box spans the image
    strip = np.zeros((h, w), np.float32)
    strip[h - 2:, w // 2:] = 1  # touches the bottom and right borders
    return {"fractional": frac, "far": far, "strip": strip, "one_pixel": one, "corner_fraction": edge, "full": np.ones((h, w), np.float32),
            "empty": np.zeros((h, w), np.float32)}


@pytest.mark.parametrize("h,w", [(24, 31), (5, 9)])
def test_masked_metrics_match_the_script(h, w):
    rng = np.random.default_rng([7, h, w])
    a, b = _img(rng, h, w), _img(rng, h, w)
    for name, raw in _masks(rng, h, w).items():
        t = raw[None].copy()
        t[t > 0.5] = 1  # the script's step, in the oracle's own terms
        wts = script_weights(raw)
        _close(masked_psnr(a, b, wts), oracle.masked_psnr(_chw(a), _chw(b), t))
        _close(masked_ssim(a, b, wts), oracle.masked_ssim(_chw(a), _chw(b), t))


def test_empty_and_identical_masks():
    rng = np.random.default_rng(3)
    a, b = _img(rng, 12, 12), _img(rng, 12, 12)
    empty = np.zeros((12, 12))
    assert math.isnan(masked_psnr(a, b, empty))
    assert masked_ssim(a, b, empty) == 1.0  # both products black: the script's perfect score
    c = b.copy()
    m = np.zeros((12, 12))
    m[2:5, 2:5] = 1
    c[2:5, 2:5] = a[2:5, 2:5]
    assert masked_psnr(a, c, m) == math.inf


def test_default_mode_refuses_empty_masks_compat_keeps_the_script_values():
    rng = np.random.default_rng(4)
    a, b = _img(rng, 12, 12), _img(rng, 12, 12)
    d = score_view("v", a, b, np.zeros((12, 12)), mode="default")
    assert d.masked_psnr is None and d.masked_ssim is None and d.reasons["masked_psnr"] == EMPTY_MASK
    c = score_view("v", a, b, np.zeros((12, 12)), mode="compat")
    assert math.isnan(c.masked_psnr) and c.masked_ssim == 1.0
    none = score_view("v", a, b, None)
    assert none.masked_psnr is None and "masks" in none.reasons["masked_psnr"]


def test_means_compat_as_printed_default_without_infinities():
    vals = [30.0, math.inf, 20.0]
    assert metric_mean(vals, [None] * 3, mode="compat").mean == math.inf
    d = metric_mean(vals, [None] * 3, mode="default")
    assert d.mean == 25.0 and d.n == 2 and d.n_infinite == 1
    m = metric_mean([None, 10.0], ["why", None], mode="default")
    assert m.mean == 10.0 and m.n_missing == 1 and m.reason == "why"
    assert metric_mean([math.nan, 1.0], [None] * 2, mode="compat").mean != metric_mean([math.nan, 1.0], [None] * 2,
                                                                                         mode="compat").mean  # nan
    rng = np.random.default_rng(5)
    views = [score_view(str(i), _img(rng, 8, 8), _img(rng, 8, 8), None) for i in range(3)]
    s = summarise("s", "m", views)
    assert s.means["psnr"].mean == pytest.approx(np.mean([v.psnr for v in views]))
    assert s.means["masked_psnr"].mean is None and s.means["masked_psnr"].n_missing == 3


def _save(tmp_path, name, im: Image.Image):
    p = tmp_path / name
    im.save(p)
    return p


def test_mask_files_read_as_pil_and_to_tensor_make_them(tmp_path):
    grey = np.array([[0, 100, 128, 255], [1, 127, 200, 0]], np.uint8)
    cases = {
        "L.png": Image.fromarray(grey, "L"),
        "one.png": Image.fromarray(grey > 100),
        "I16.png": Image.fromarray(np.array([[0, 1000, 40000, 65535], [1, 2, 3, 0]], np.uint16)),
    }
    pal = Image.fromarray(grey, "P")
    pal.putpalette([i for c in range(256) for i in (c, 0, 0)])
    cases["P.png"] = pal
    for name, im in cases.items():
        p = _save(tmp_path, name, im)
        expect = oracle.read_mask(p)[0]
        np.testing.assert_array_equal(script_weights(read_mask_script(p)), expect.astype(np.float64), err_msg=name)
    # 16-bit values above 32767 wrap to negative int16, as to_tensor's np.int16 makes them
    w = script_weights(read_mask_script(tmp_path / "I16.png"))
    assert w[0].tolist() == [0.0, 1.0, -25536.0, -1.0]
    # values in (0, 0.5] stay fractional
    assert script_weights(read_mask_script(tmp_path / "L.png"))[0, 1] == pytest.approx(100 / 255)


def test_multichannel_masks_fail_in_compat_read_in_default(tmp_path):
    rgb = np.zeros((4, 5, 3), np.uint8)
    rgb[1, 2] = (0, 9, 0)
    p = _save(tmp_path, "rgb.png", Image.fromarray(rgb, "RGB"))
    with pytest.raises(InputError, match="3 channels") as e:
        read_mask_script(p)
    assert str(p) in str(e.value)
    with pytest.raises(IndexError):  # what the script itself does
        oracle.masked_psnr(np.zeros((3, 4, 5), np.float32), np.zeros((3, 4, 5), np.float32), oracle.read_mask(p))
    b = read_mask_binary(p, (4, 5))
    assert b.sum() == 1 and b[1, 2] == 1
    with pytest.raises(InputError, match="5x4"):
        read_mask_binary(p, (5, 4))


def test_natural_order_as_natsort():
    names = ["IMG_10.jpg", "IMG_2.jpg", "IMG_1.jpg", "a.jpg", "IMG_02b.jpg", "00003.png", "00010.png"]
    assert sorted(names, key=natural_key) == [p.name for p in oracle.natsorted_paths(
        [__import__("pathlib").Path(n) for n in names])]
    assert sorted(["v10", "v9", "v100"], key=natural_key) == ["v9", "v10", "v100"]


def test_the_benchs_separable_model_equals_the_literal_one():
    """bench/inpaint_vs_script.py times the separable form of the script's 11x11 correlation."""
    rng = np.random.default_rng(9)
    a, b = _chw(_img(rng, 20, 27)), _chw(_img(rng, 20, 27))
    assert abs(oracle.ssim(a, b, separable=True) - oracle.ssim(a, b)) <= 1e-6


def test_16_bit_images_full_depth_in_default_as_pil_clips_them_in_compat(tmp_path):
    from r360gpu.io.inpaint_folders import read_image
    from r360gpu.util.warning_log import collecting

    grey = np.array([[0, 200, 300, 65535]], np.uint16)
    p = tmp_path / "g16.png"
    Image.fromarray(grey).save(p)
    with collecting(None) as log:
        full = read_image(p)
        script = read_image(p, compat=True)
    np.testing.assert_allclose(full[0, :, 0], grey[0] / 65535, atol=1e-7)
    np.testing.assert_array_equal(script, oracle.read_rgb(p).transpose(1, 2, 0))  # PIL's own conversion
    assert not np.allclose(script, full)
    assert len(log.records()) == 2 and all("I;16" in r["message"] for r in log.records())
