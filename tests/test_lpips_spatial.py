"""Spatial LPIPS exports and masked LPIPS (r360gpu/metrics/fidelity.py) on tiny ONNX graphs.

The stand-in "spatial LPIPS" returns the per-pixel map ``mean_c(a * a - b)`` (N, 1, H, W): it
tells the two inputs apart and shows whether they were mapped to [-1, 1].  The stand-in
plain export returns that map's mean.  masked_lpips is checked against the 360-USID
script's arithmetic written out by hand.
"""
from __future__ import annotations

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
from onnx import helper  # noqa: E402

from r360gpu.errors import InputError  # noqa: E402
from r360gpu.metrics.fidelity import LpipsModel, masked_lpips, script_mask_weights  # noqa: E402

from onnx_graphs import F, save_model, value_info  # noqa: E402


def lpips_like(path, *, spatial=True, out_shape=None, hw=("H", "W")):
    nodes = [
        helper.make_node("Mul", ["in0", "in0"], ["sq"]),
        helper.make_node("Sub", ["sq", "in1"], ["d"]),
        helper.make_node("ReduceMean", ["d"], ["map"], axes=[1], keepdims=1),
    ]
    out = "map"
    if not spatial:
        nodes.append(helper.make_node("ReduceMean", ["map"], ["dist"], axes=[2, 3], keepdims=1))
        out = "dist"
    if out_shape is not None:
        # Reshape to its own runtime shape: onnxruntime cannot infer the output's dimensions.
        nodes += [helper.make_node("Shape", [out], ["own_shape"]),
                  helper.make_node("Reshape", [out, "own_shape"], ["open"])]
        out = "open"
    if out_shape is None:
        out_shape = ["N", 1, *hw] if spatial else ["N", 1, 1, 1]
    inputs = [value_info(n, F, ["N", 3, *hw]) for n in ("in0", "in1")]
    return save_model(path, nodes, inputs, [value_info(out, F, out_shape)])


def expected_map(x, y, normalize=True):
    if normalize:
        x, y = 2 * x - 1, 2 * y - 1
    return np.mean(x * x - y, axis=2)


RNG = np.random.default_rng(11)
X, Y = RNG.random((13, 17, 3)), RNG.random((13, 17, 3))


@pytest.mark.parametrize("normalize", [True, False])
def test_distance_map_of_a_spatial_export(tmp_path, normalize):
    lp = LpipsModel(lpips_like(tmp_path / "lpips_vgg_spatial.onnx"))
    lmap = lp.distance_map(X, Y, normalize=normalize)
    assert lmap.shape == (13, 17) and lmap.dtype == np.float64
    np.testing.assert_allclose(lmap, expected_map(X, Y, normalize), atol=1e-6)
    assert lp.spatial is True


@pytest.mark.parametrize("normalize", [True, False])
def test_plain_export_distance_and_the_normalize_flag(tmp_path, normalize):
    lp = LpipsModel(lpips_like(tmp_path / "lpips_vgg.onnx", spatial=False))
    assert lp.spatial is False
    got = lp.distance(X, Y, normalize=normalize)
    assert got == pytest.approx(expected_map(X, Y, normalize).mean(), abs=1e-6)
    # uint8 images are divided by 255 before either mapping.
    u8 = (X * 255).round().astype(np.uint8), (Y * 255).round().astype(np.uint8)
    assert lp.distance(*u8, normalize=normalize) == pytest.approx(
        expected_map(u8[0] / 255.0, u8[1] / 255.0, normalize).mean(), abs=1e-6
    )


def test_each_export_is_refused_where_the_other_is_needed(tmp_path):
    spatial = LpipsModel(lpips_like(tmp_path / "sp.onnx"))
    with pytest.raises(InputError, match=r"sp.onnx.*spatial LPIPS export"):
        spatial.distance(X, Y)
    plain = LpipsModel(lpips_like(tmp_path / "plain.onnx", spatial=False))
    with pytest.raises(InputError, match=r"plain.onnx.*not a map"):
        plain.distance_map(X, Y)


@pytest.mark.parametrize("spatial", [True, False])
def test_an_open_declared_shape_is_decided_by_the_first_run(tmp_path, spatial):
    lp = LpipsModel(lpips_like(tmp_path / "open.onnx", spatial=spatial, out_shape=["N", "a", "b", "c"]))
    assert lp.spatial is None
    if spatial:
        with pytest.raises(InputError, match="spatial LPIPS export"):
            lp.distance(X, Y)
        assert lp.spatial is True
        assert lp.distance_map(X, Y).shape == (13, 17)
    else:
        with pytest.raises(InputError, match="not a map"):
            lp.distance_map(X, Y)
        assert lp.spatial is False
        assert np.isfinite(lp.distance(X, Y))


def test_declared_fixed_map_shape_is_spatial(tmp_path):
    lp = LpipsModel(lpips_like(tmp_path / "fixed.onnx", hw=(13, 17)))
    assert lp.spatial is True
    with pytest.raises(InputError, match="spatial LPIPS export"):
        lp.distance(X, Y)


def test_an_output_of_another_size_is_refused(tmp_path):
    path = tmp_path / "odd.onnx"
    nodes = [helper.make_node("ReduceMean", ["in0"], ["m"], axes=[2], keepdims=1)]  # (N, 3, 1, W)
    save_model(path, nodes, [value_info(n, F, ["N", 3, "H", "W"]) for n in ("in0", "in1")],
               [value_info("m", F, ["N", 3, 1, "W"])])
    with pytest.raises(InputError, match=r"odd.onnx.*expected one distance or a \(1, 1, 13, 17\) map"):
        LpipsModel(path).distance_map(X, Y)


def script_masked(lmap, mask_u8):
    """aura_eval.py's arithmetic: to_tensor, values above 0.5 set to 1, sum(map * mask) / sum(mask)."""
    m = mask_u8.astype(np.float32) / np.float32(255)
    if m.ndim == 2:
        m = m[None]
    else:
        m = m.transpose(2, 0, 1)[:3]
    m[m > 0.5] = 1
    return float(np.sum(lmap[None] * m) / np.sum(m))


def test_masked_lpips_keeps_fractional_weights_up_to_one_half():
    lmap = RNG.random((6, 5))
    mask = np.zeros((6, 5), np.uint8)
    mask[0, :] = 255
    mask[1, :] = 128  # 0.502 -> 1
    mask[2, :] = 127  # 0.498 stays
    mask[3, :] = 64
    w = np.array([1.0, 1.0, 127 / 255, 64 / 255])
    by_hand = float(np.sum(lmap[:4] * w[:, None]) / (5 * w.sum()))
    assert masked_lpips(lmap, mask) == pytest.approx(by_hand, rel=1e-12)
    assert masked_lpips(lmap, mask) == pytest.approx(script_masked(lmap, mask), rel=1e-6)
    np.testing.assert_array_equal(script_mask_weights(mask)[:, 0, 0], [1, 1, 127 / 255, 64 / 255, 0, 0])


def test_masked_lpips_mask_kinds_and_channels():
    lmap = RNG.random((7, 9))
    rgb = RNG.integers(0, 256, (7, 9, 3), dtype=np.uint8)
    assert masked_lpips(lmap, rgb) == pytest.approx(script_masked(lmap, rgb), rel=1e-6)
    binary = RNG.random((7, 9)) > 0.5
    assert masked_lpips(lmap, binary) == pytest.approx(lmap[binary].mean(), rel=1e-12)
    assert masked_lpips(lmap[None, None], binary.astype(np.float32)) == pytest.approx(lmap[binary].mean(), rel=1e-12)
    # A spatial map's masked mean over the whole image is its plain mean.
    assert masked_lpips(lmap, np.full((7, 9), 255, np.uint8)) == pytest.approx(lmap.mean(), rel=1e-12)


def test_masked_lpips_empty_and_bad_masks():
    lmap = RNG.random((4, 4))
    assert masked_lpips(lmap, np.zeros((4, 4), np.uint8)) is None
    for bad, match in [
        (np.ones((4, 5), np.uint8), "sizes differ"),
        (np.ones((4, 4, 4), np.uint8), "C <= 3"),
        (np.full((4, 4), 2.0), "outside"),
        (np.full((4, 4), np.nan), "non-finite"),
        (np.ones((4, 4), np.int32), "uint8, bool or float"),
    ]:
        with pytest.raises(InputError, match=match):
            masked_lpips(lmap, bad)
