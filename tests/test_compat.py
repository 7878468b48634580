"""Tests of r360gpu.metrics.compat against matplotlib, PIL and OpenCV doing what the reference code does."""
from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from PIL import Image  # noqa: E402

from r360gpu.errors import InputError  # noqa: E402
from r360gpu.metrics.compat import (  # noqa: E402
    _GRAY_R,
    CompatResult,
    compat_changed,
    compat_quantise,
    depth_delta,
)
from r360gpu.metrics.ght import ght  # noqa: E402


# --- the reference steps, done with the libraries the reference uses ---------------------

def reference_gray(delta: np.ndarray, target=None) -> np.ndarray:
    """imsave(cmap=gray_r) to PNG, PIL read-back as RGBA, max over R, G, B."""
    target = io.BytesIO() if target is None else target
    plt.imsave(target, delta, cmap=plt.cm.gray_r, format="png")
    if isinstance(target, io.BytesIO):
        target.seek(0)
    rgba = np.array(Image.open(target))
    assert rgba.ndim == 3 and rgba.shape[-1] == 4 and np.all(rgba[..., 3] == 255)
    return np.amax(rgba[..., :3], axis=-1)


def reference_changed(gray: np.ndarray):
    """Histogram with edges -0.5..255.5 at positions 0..255, GHT(1000, 300, 0, 0), gray < t."""
    hist, _ = np.histogram(gray.ravel(), np.arange(-0.5, 256.5))
    t = ght(hist, np.arange(256), nu=1000, tau=300, kappa=0.0, omega=0.0).threshold
    return gray < t, t, hist


def reference_mask_roundtrip(mask: np.ndarray, path=None) -> np.ndarray:
    """imsave(mask, cmap=gray_r), cv2 grayscale read-back, changed = value != 255."""
    buf = io.BytesIO()
    plt.imsave(path if path is not None else buf, mask, cmap=plt.cm.gray_r, format="png")
    if path is not None:
        back = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    else:
        back = cv2.imdecode(np.frombuffer(buf.getvalue(), np.uint8), cv2.IMREAD_GRAYSCALE)
    return back != 255


def test_gray_r_table_matches_matplotlib():
    rgba = plt.get_cmap("gray_r")(np.arange(256), bytes=True)
    for channel in range(3):
        np.testing.assert_array_equal(rgba[:, channel], _GRAY_R)
    # The table is not 255 - i: truncation merges neighbouring entries.
    assert np.any(_GRAY_R != 255 - np.arange(256))
    assert _GRAY_R[0] == 255 and _GRAY_R[254] == _GRAY_R[255] == 0


# --- deterministic families of |dD| images -----------------------------------------------

def delta_family(kind: str, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    shape = tuple(int(s) for s in rng.integers(1, 48, 2))
    if kind == "uniform":
        return rng.random(shape, dtype=np.float32)
    if kind == "reference_8bit":
        # What the reference sees: |difference| of 8-bit depths with zeros for missing depth.
        pre = rng.integers(0, 256, shape) * (rng.random(shape) > 0.1)
        post = np.where(rng.random(shape) < 0.3, rng.integers(0, 256, shape), pre)
        return depth_delta(pre, post)
    if kind == "bimodal":
        small = np.abs(rng.normal(0, 0.02, shape))
        large = rng.normal(rng.uniform(0.5, 3.0), 0.2, shape)
        return np.abs(np.where(rng.random(shape) < 0.2, large, small)).astype(np.float32)
    if kind == "large_range":
        return (rng.exponential(1.0, shape) * 10.0 ** rng.uniform(-20, 30)).astype(np.float32)
    if kind == "bin_edges":
        # Values on and one ulp beside the edges k/256 of the normalised range.
        lo, hi = np.float32(rng.uniform(0, 10)), np.float32(rng.uniform(10, 1e4))
        k = rng.integers(0, 257, shape)
        a = (np.float64(lo) + k / 256.0 * (np.float64(hi) - np.float64(lo))).astype(np.float32)
        a = np.nextafter(a, rng.choice([-np.inf, 0.0, np.inf], shape).astype(np.float32))
        a = np.clip(a, lo, hi)
        a.flat[0], a.flat[-1] = lo, hi
        return a
    if kind == "constant":
        return np.full(shape, np.float32(rng.uniform(0, 5)))
    if kind == "zero":
        return np.zeros(shape, np.float32)
    if kind == "one_pixel":
        return np.array([[rng.uniform(0, 5)]], np.float32)
    if kind == "two_values":
        return rng.choice(np.float32([0.0, rng.uniform(0.1, 9.0)]), shape)
    if kind == "odd_sizes":
        return rng.random((int(rng.choice([1, 3, 7, 31])), int(rng.choice([1, 5, 13, 33]))),
                          dtype=np.float32)
    raise AssertionError(kind)


KINDS = ["uniform", "reference_8bit", "bimodal", "large_range", "bin_edges", "constant", "zero",
         "one_pixel", "two_values", "odd_sizes"]
CASES = [(kind, seed) for kind in KINDS for seed in range(6)]


@pytest.mark.parametrize("kind, seed", CASES)
def test_quantise_and_mask_match_the_reference_bit_for_bit(kind, seed, tmp_path):
    delta = delta_family(kind, seed)
    gray_ref = reference_gray(delta, tmp_path / "interm.png")
    gray = compat_quantise(delta)
    assert gray.dtype == np.uint8 and gray.shape == delta.shape
    np.testing.assert_array_equal(gray, gray_ref)

    changed_ref, t_ref, hist_ref = reference_changed(gray_ref)
    res = compat_changed(delta)
    assert isinstance(res, CompatResult)
    assert res.changed.dtype == np.bool_
    np.testing.assert_array_equal(res.changed, changed_ref)
    assert res.threshold == t_ref
    np.testing.assert_array_equal(res.hist, hist_ref)

    # The reference stores the mask as a gray_r PNG and reads "changed" as != 255.
    np.testing.assert_array_equal(reference_mask_roundtrip(res.changed, tmp_path / "mask.png"), res.changed)


@settings(max_examples=80, deadline=None)
@given(
    delta=hnp.arrays(
        np.float32,
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=24),
        elements=st.floats(0.0, float(np.float32(3e38)), width=32, allow_nan=False, allow_infinity=False),
    )
)
def test_quantise_matches_matplotlib_on_arbitrary_floats(delta):
    gray_ref = reference_gray(delta)
    np.testing.assert_array_equal(compat_quantise(delta), gray_ref)
    res = compat_changed(delta)
    changed_ref, t_ref, _ = reference_changed(gray_ref)
    np.testing.assert_array_equal(res.changed, changed_ref)
    assert res.threshold == t_ref
    assert not res.changed.all()
    np.testing.assert_array_equal(reference_mask_roundtrip(res.changed), res.changed)


def test_large_changes_are_the_changed_ones():
    # gray_r puts large |dD| in dark levels, so "gray < t" selects the large ones.
    rng = np.random.default_rng(5)
    delta = np.abs(rng.normal(0, 0.01, (128, 128))).astype(np.float32)
    delta[40:80, 40:80] = rng.uniform(2.0, 3.0, (40, 40))
    res = compat_changed(delta)
    expected = np.zeros_like(res.changed)
    expected[40:80, 40:80] = True
    np.testing.assert_array_equal(res.changed, expected)


def test_reference_prior_dominates_small_images():
    # The same picture at 64 x 64: the prior (nu = 1000 pseudo-counts, tau = 300
    # gray levels) outweighs 4096 pixels and GHT splits off gray level 0 alone;
    # "gray < 0" then marks nothing.  This is the reference's behaviour too.
    rng = np.random.default_rng(5)
    delta = np.abs(rng.normal(0, 0.01, (64, 64))).astype(np.float32)
    delta[20:40, 20:40] = rng.uniform(2.0, 3.0, (20, 20))
    res = compat_changed(delta)
    assert res.threshold == 0.0
    assert not res.changed.any()
    assert compat_changed(delta, nu=0.0, tau=0.0).changed[20:40, 20:40].all()


def test_constant_delta_changes_nothing():
    res = compat_changed(np.full((5, 7), 3.25, np.float32))
    assert not res.changed.any()
    assert res.hist[255] == 35 and res.hist.sum() == 35
    assert res.threshold == 127.0
    np.testing.assert_array_equal(compat_quantise(np.full((2, 2), 9.0)), np.full((2, 2), 255, np.uint8))


def test_float64_input_is_quantised_as_float32():
    rng = np.random.default_rng(11)
    delta = rng.random((13, 17)) * 7.0
    np.testing.assert_array_equal(compat_quantise(delta), reference_gray(delta.astype(np.float32)))


@pytest.mark.parametrize(
    "bad",
    [np.zeros((2, 2, 3), np.float32), np.zeros((0, 4), np.float32), np.zeros(5, np.float32),
     np.array([[1.0, np.nan]]), np.array([[1.0, np.inf]]), np.array([[1.0, 1e39]]),
     np.array([["a", "b"]])],
)
def test_bad_delta_raises_input_error(bad):
    with pytest.raises(InputError):
        compat_quantise(bad)
    with pytest.raises(InputError):
        compat_changed(bad)


# --- depth_delta: the missing-depth rule ----------------------------------------------------

def reference_style_delta(pre_u8: np.ndarray, post_u8: np.ndarray) -> np.ndarray:
    """The reference's rule on 8-bit depths: post - pre in float32, zeroed where the
    difference equals post (pre is 0) or equals -pre (post is 0), then absolute value."""
    diff = post_u8.astype(np.float32) - pre_u8.astype(np.float32)
    missing = (diff == post_u8.astype(np.float32)) | (diff == -pre_u8.astype(np.float32))
    return np.abs(np.where(missing, np.float32(0), diff))


@pytest.mark.parametrize("seed", range(5))
def test_depth_delta_matches_reference_rule_on_8bit_depths(seed):
    rng = np.random.default_rng(400 + seed)
    shape = (int(rng.integers(1, 40)), int(rng.integers(1, 40)))
    pre = (rng.integers(0, 256, shape) * (rng.random(shape) > 0.2)).astype(np.uint8)
    post = (rng.integers(0, 256, shape) * (rng.random(shape) > 0.2)).astype(np.uint8)
    out = depth_delta(pre, post)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, reference_style_delta(pre, post))


def test_depth_delta_on_float_depths():
    pre = np.array([[0.0, 1.5, 2.0, 1e-6, np.nan, 1.0, 4.0, -1.0]], np.float32)
    post = np.array([[3.0, 0.0, 2.5, 1e6, 1.0, np.inf, 4.0, 2.0]], np.float32)
    # Zero, NaN, inf and negative depths are missing; 1e-6 beside 1e6 is a real change.
    expected = np.float32([[0.0, 0.0, 0.5, 1e6 - 1e-6, 0.0, 0.0, 0.0, 0.0]])
    out = depth_delta(pre, post)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, expected)


@pytest.mark.parametrize(
    "pre, post",
    [(np.zeros((2, 3)), np.zeros((3, 2))), (np.zeros(4), np.zeros(4)),
     (np.zeros((0, 0)), np.zeros((0, 0))), (np.array([["a"]]), np.array([["b"]]))],
)
def test_depth_delta_rejects_bad_input(pre, post):
    with pytest.raises(InputError):
        depth_delta(pre, post)
