"""Fidelity: PSNR and SSIM against hand-computed values and a windowed numpy oracle;
LPIPS through a small ONNX graph with the LPIPS signature."""
from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.fidelity import (
    NO_LPIPS_MODEL,
    FidelityView,
    LpipsModel,
    fidelity_summary,
    fidelity_view,
    psnr,
    ssim,
)

C1, C2 = 0.01**2, 0.03**2


def _g1():
    k = np.arange(11) - 5.0
    g = np.exp(-k * k / (2 * 1.5**2))
    return g / g.sum()


def _ssim_oracle(x, y):
    """Window by window, with an explicit 11 x 11 weight matrix."""
    i, j = np.mgrid[0:11, 0:11]
    w = np.exp(-((i - 5.0) ** 2 + (j - 5.0) ** 2) / (2 * 1.5**2))
    w /= w.sum()
    h, wd, c = x.shape
    vals = []
    for ch in range(c):
        for r in range(h - 10):
            for q in range(wd - 10):
                a = x[r : r + 11, q : q + 11, ch]
                b = y[r : r + 11, q : q + 11, ch]
                ma, mb = (w * a).sum(), (w * b).sum()
                va, vb = (w * (a - ma) ** 2).sum(), (w * (b - mb) ** 2).sum()
                cov = (w * (a - ma) * (b - mb)).sum()
                vals.append(((2 * ma * mb + C1) * (2 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2)))
    return float(np.mean(vals))


def test_psnr_hand_values():
    a = np.zeros((4, 5, 3))
    assert psnr(a, np.full((4, 5, 3), 0.1)) == pytest.approx(20.0, abs=1e-12)
    u = np.zeros((4, 5, 3), np.uint8)
    assert psnr(u, np.full((4, 5, 3), 51, np.uint8)) == pytest.approx(10 * math.log10(1 / 0.04), abs=1e-12)
    half = a.copy()
    half[:2] = 1.0  # MSE = 0.5
    assert psnr(a, half) == pytest.approx(10 * math.log10(2.0), abs=1e-12)
    assert psnr(a, a) == math.inf


def test_ssim_identity_and_symmetry():
    rng = np.random.default_rng(0)
    x = rng.random((16, 19, 3))
    y = np.clip(x + rng.normal(0, 0.1, x.shape), 0, 1)
    assert ssim(x, x) == pytest.approx(1.0, abs=1e-12)
    assert ssim(x, y) == pytest.approx(ssim(y, x), abs=1e-15)
    assert ssim(x, y) < 1.0


def test_ssim_constant_images_hand_value():
    a, b = 0.5, 0.25
    x = np.full((12, 14, 3), a)
    y = np.full((12, 14, 3), b)
    assert ssim(x, y) == pytest.approx((2 * a * b + C1) / (a * a + b * b + C1), abs=1e-12)


def test_ssim_ramp_closed_forms():
    # x = alpha * column + beta: every window's mean is the centre value and its
    # variance alpha^2 * s with s the second moment of the 1-D window.
    h, w, alpha, beta = 13, 20, 0.02, 0.3
    x = np.broadcast_to(alpha * np.arange(w) + beta, (h, w))[:, :, None].repeat(3, axis=2)
    s = float((_g1() * (np.arange(11) - 5.0) ** 2).sum())
    mu = alpha * np.arange(5, w - 5) + beta
    var = alpha**2 * s
    d = 0.05  # y = x + d: contrast-structure term is 1
    expect_shift = np.mean((2 * mu * (mu + d) + C1) / (mu**2 + (mu + d) ** 2 + C1))
    assert ssim(x, x + d) == pytest.approx(expect_shift, abs=1e-10)
    k = 0.6  # y = k x
    expect_scale = np.mean(
        (2 * k * mu**2 + C1) / ((1 + k * k) * mu**2 + C1) * (2 * k * var + C2) / ((1 + k * k) * var + C2)
    )
    assert ssim(x, k * x) == pytest.approx(expect_scale, abs=1e-10)


def test_ssim_matches_window_oracle():
    rng = np.random.default_rng(1)
    x = rng.random((14, 17, 3))
    y = np.clip(0.7 * x + 0.2 * rng.random(x.shape), 0, 1)
    assert ssim(x, y) == pytest.approx(_ssim_oracle(x, y), abs=1e-12)
    g = rng.random((13, 12))  # gray (H, W)
    assert ssim(g, g[::-1]) == pytest.approx(_ssim_oracle(g[:, :, None], g[::-1, :, None]), abs=1e-12)


def test_uint8_is_scaled():
    rng = np.random.default_rng(2)
    u = rng.integers(0, 256, (12, 12, 3), dtype=np.uint8)
    v = rng.integers(0, 256, (12, 12, 3), dtype=np.uint8)
    assert ssim(u, v) == pytest.approx(ssim(u / 255.0, v / 255.0), abs=1e-15)
    assert psnr(u, v) == pytest.approx(psnr(u / 255.0, v / 255.0), abs=1e-12)


def test_bad_images():
    ok = np.zeros((12, 12, 3))
    with pytest.raises(InputError, match="outside"):
        psnr(ok, np.full((12, 12, 3), 1.5))
    with pytest.raises(InputError, match="NaN"):
        psnr(ok, np.full((12, 12, 3), np.nan))
    with pytest.raises(InputError, match="I_ref"):
        psnr(ok, np.zeros((12, 13, 3)))
    with pytest.raises(InputError, match="at least 11x11"):
        ssim(np.zeros((10, 30, 3)), np.zeros((10, 30, 3)))
    with pytest.raises(InputError):
        psnr(np.zeros((12, 12, 4)), np.zeros((12, 12, 4)))


def test_without_lpips_model_not_computed():
    x = np.zeros((12, 12, 3))
    v = fidelity_view(x, x)
    assert v.lpips is None and v.lpips_reason == NO_LPIPS_MODEL and v.lpips_model is None
    assert v.psnr == math.inf and v.ssim == pytest.approx(1.0)


def test_summary_reports_identical_views_separately():
    x = np.zeros((12, 12, 3))
    views = [fidelity_view(x, x), fidelity_view(x, np.full_like(x, 0.1)), fidelity_view(x, np.full_like(x, 0.01))]
    s = fidelity_summary(views)
    assert s.psnr == pytest.approx((20.0 + 40.0) / 2) and s.psnr_n_identical == 1
    assert s.lpips is None and "3 of 3" in s.lpips_reason
    assert fidelity_summary(views[:1]).psnr == math.inf
    assert fidelity_summary([]).psnr is None
    d = json.loads(json.dumps(s.to_dict(), allow_nan=False))
    assert d["psnr_n_identical"] == 1


def _lpips_like_model(path, *, names=("img_a", "img_b"), op="sqdiff", n_inputs=2, hw=("H", "W")):
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    inputs = [helper.make_tensor_value_info(n, TensorProto.FLOAT, [1, 3, *hw]) for n in names[:n_inputs]]
    out = helper.make_tensor_value_info("dist", TensorProto.FLOAT, [1, 1, 1, 1])
    if n_inputs == 1:
        nodes = [helper.make_node("ReduceMean", [names[0]], ["dist"], keepdims=1)]
    elif op == "sqdiff":
        nodes = [
            helper.make_node("Sub", list(names), ["d"]),
            helper.make_node("Mul", ["d", "d"], ["d2"]),
            helper.make_node("ReduceMean", ["d2"], ["dist"], keepdims=1),
        ]
    else:  # signed mean difference: tells the two inputs apart
        nodes = [helper.make_node("Sub", list(names), ["d"]), helper.make_node("ReduceMean", ["d"], ["dist"], keepdims=1)]
    graph = helper.make_graph(nodes, "lpips_like", inputs, [out])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return path


def test_lpips_through_onnx_model(tmp_path):
    path = _lpips_like_model(tmp_path / "lpips_alex.onnx")
    lp = LpipsModel(path)
    assert lp.input_names == ("img_a", "img_b")
    rng = np.random.default_rng(3)
    x, y = rng.random((12, 15, 3)), rng.random((12, 15, 3))
    v = fidelity_view(x, y, lp)
    # Inputs are mapped to [-1, 1], so the mean squared difference is 4 x MSE.
    assert v.lpips == pytest.approx(4 * np.mean((x - y) ** 2), rel=1e-5)
    assert v.lpips_reason is None
    assert v.lpips_model["file"] == "lpips_alex.onnx"
    assert v.lpips_model["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    s = fidelity_summary([v, fidelity_view(y, x, lp)])
    assert s.lpips == pytest.approx(v.lpips, rel=1e-5) and s.lpips_reason is None
    d = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    assert FidelityView.from_dict(d) == v


def test_lpips_input_order_comes_from_the_model(tmp_path):
    # Declared order (zeta, alpha) is not alphabetical: the first input gets I_post.
    lp = LpipsModel(_lpips_like_model(tmp_path / "m.onnx", names=("zeta", "alpha"), op="diff"))
    x, y = np.full((12, 12, 3), 0.75), np.full((12, 12, 3), 0.25)
    assert lp.input_names == ("zeta", "alpha")
    assert lp.distance(x, y) == pytest.approx(1.0, abs=1e-6)  # (2*0.75-1) - (2*0.25-1)


def test_lpips_bad_models(tmp_path):
    with pytest.raises(InputError, match="not found"):
        LpipsModel(tmp_path / "missing.onnx")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(InputError, match="junk.onnx"):
        LpipsModel(junk)
    with pytest.raises(InputError, match="two image inputs"):
        LpipsModel(_lpips_like_model(tmp_path / "one.onnx", n_inputs=1))
    fixed = LpipsModel(_lpips_like_model(tmp_path / "fixed.onnx", hw=(64, 64)))
    with pytest.raises(InputError, match="fixed shape"):
        fixed.distance(np.zeros((12, 12, 3)), np.zeros((12, 12, 3)))


def test_record_round_trip_with_inf():
    x = np.zeros((12, 12, 3))
    v = fidelity_view(x, x)
    d = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    back = FidelityView.from_dict(d)
    assert back == v and back.psnr == math.inf
