"""Tests of r360gpu.metrics.compat against matplotlib, PIL and OpenCV doing what the public scripts do.

The public code is modelled line by line with its dtypes (uint8 depths from PIL, float32
differences, the uint8 negation that wraps); the folder-level parity against the public
modules themselves is in tests/test_compat_public.py."""
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
    check_compat,
    compat_changed,
    compat_quantise,
    depth_delta,
    public_changed,
    public_delta,
    read_depth_public,
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
        # What the scripts see: |difference| of 8-bit depths under their missing-depth rule.
        pre = (rng.integers(0, 256, shape) * (rng.random(shape) > 0.1)).astype(np.uint8)
        post = np.where(rng.random(shape) < 0.3, rng.integers(0, 256, shape), pre).astype(np.uint8)
        return public_delta(pre, post)
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


# --- the public scripts' missing-depth rule, modelled with their exact dtypes ---------------

def public_script_delta(depth1: np.ndarray, depth2: np.ndarray) -> np.ndarray:
    """depth_diff.py's lines as they run: depth1 (before) and depth2 (after) are the uint8
    arrays of PIL convert("L"), so ``-depth1`` is uint8 negation, which wraps modulo 256."""
    assert depth1.dtype == np.uint8 and depth2.dtype == np.uint8
    diff = depth2.astype(np.float32) - depth1.astype(np.float32)
    diff[(diff == depth2) | (diff == -depth1)] = 0
    return np.abs(diff)


def adversarial_pairs():
    rng = np.random.default_rng(1000)
    v = np.arange(256, dtype=np.uint8)
    pre_all, post_all = np.meshgrid(v, v)  # every (pre, post) pair of 8-bit values once
    yield "all_pairs", pre_all, post_all
    yield "post_zero", v[None, :], np.zeros((1, 256), np.uint8)
    yield "pre_zero", np.zeros((1, 256), np.uint8), v[None, :]
    yield "both_zero", np.zeros((3, 4), np.uint8), np.zeros((3, 4), np.uint8)
    yield "equal", v[None, :], v[None, :]
    yield "pre_128", np.full((1, 256), 128, np.uint8), v[None, :]
    for seed in range(3):
        shape = (int(rng.integers(1, 40)), int(rng.integers(1, 40)))
        pre = (rng.integers(0, 256, shape) * (rng.random(shape) > 0.2)).astype(np.uint8)
        post = (rng.integers(0, 256, shape) * (rng.random(shape) > 0.2)).astype(np.uint8)
        yield f"random{seed}", pre, post


@pytest.mark.parametrize("name, pre, post", list(adversarial_pairs()), ids=lambda x: x if isinstance(x, str) else "")
def test_public_delta_is_the_scripts_rule_bit_for_bit(name, pre, post):
    out = public_delta(pre, post)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out, public_script_delta(pre, post))


def test_only_post_missing_keeps_the_pre_depth():
    pre = np.array([[0, 0, 7, 200, 128, 255]], np.uint8)
    post = np.array([[0, 9, 0, 0, 0, 255]], np.uint8)
    # pre 0: zeroed; post 0 alone: |dD| = D_pre (the uint8 wrap makes "diff == -pre" miss it).
    np.testing.assert_array_equal(public_delta(pre, post), np.float32([[0, 0, 7, 200, 128, 0]]))
    np.testing.assert_array_equal(public_script_delta(pre, post), np.float32([[0, 0, 7, 200, 128, 0]]))
    # r360gpu's own rule (paper mode, pictures) zeroes both kinds of hole.
    np.testing.assert_array_equal(depth_delta(pre, post), np.float32([[0, 0, 0, 0, 0, 0]]))


def test_public_delta_on_float_depths_applies_the_effective_rule():
    pre = np.array([[0.0, 1.5, 2.0, np.nan, 1.0, 4.0, -1.0, 3.0]], np.float32)
    post = np.array([[3.0, 0.0, 2.5, 1.0, np.inf, 4.0, 2.0, -2.0]], np.float32)
    expected = np.float32([[0.0, 1.5, 0.5, 0.0, 1.0, 0.0, 0.0, 3.0]])
    np.testing.assert_array_equal(public_delta(pre, post), expected)


def _png(path, arr, mode=None):
    img = Image.fromarray(arr)
    (img if mode is None else img.convert(mode)).save(path)
    return path


def test_depth_is_read_as_pil_convert_L(tmp_path):
    # 16-bit: PIL clips at 255; RGB: ITU-R 601 luma (299 R + 587 G + 114 B) / 1000; palette: its colours.
    p16 = tmp_path / "d16.png"
    assert cv2.imwrite(str(p16), np.array([[0, 100, 255, 256, 300, 65535]], np.uint16))
    np.testing.assert_array_equal(read_depth_public(p16), [[0, 100, 255, 255, 255, 255]])
    rgb = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]]], np.uint8)
    np.testing.assert_array_equal(read_depth_public(_png(tmp_path / "rgb.png", rgb)), [[76, 150, 29, 18]])
    grey = np.array([[0, 7, 100, 255]], np.uint8)
    np.testing.assert_array_equal(read_depth_public(_png(tmp_path / "p.png", grey, "P")), grey)
    np.testing.assert_array_equal(read_depth_public(_png(tmp_path / "g.png", grey)), grey)
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="bad.png"):
        read_depth_public(tmp_path / "bad.png")


def public_script_changed(delta: np.ndarray, save_intermediate: bool, tmp_path) -> np.ndarray:
    """process_depth_pair's thresholding and evaluate_depth_scene's read-back, with matplotlib,
    PIL and OpenCV: the intermediate round trip (or the raw uint8 cast), the 256-level
    histogram, GHT, ``im_bw < t``, the mask saved with imsave(gray_r) and read as != 255."""
    if save_intermediate:
        im = np.array(Image.open(_imsave(tmp_path / "interm.png", delta)))
    else:
        im = np.clip(delta, 0, 255).astype(np.uint8)
    im_bw = np.amax(im[..., :3], axis=-1) if im.ndim == 3 else im
    n, _ = np.histogram(im_bw.ravel(), np.arange(-0.5, 256.5))
    t = ght(n, np.arange(256), nu=1000, tau=300, kappa=0.0, omega=0.0).threshold
    back = cv2.imread(str(_imsave(tmp_path / "final.png", im_bw < t)), cv2.IMREAD_GRAYSCALE)
    return back != 255


def _imsave(path, arr):
    plt.imsave(str(path), arr, cmap=plt.cm.gray_r)
    return path


def _delta_cases():
    rng = np.random.default_rng(77)
    yield "constant", np.full((20, 30), 20, np.float32)
    yield "zero", np.zeros((20, 30), np.float32)
    for name, pre, post in adversarial_pairs():
        yield name, public_script_delta(pre, post)
    big = np.zeros((96, 128), np.float32)
    big[30:70, 40:90] = rng.integers(120, 180, (40, 50))
    big[35:45, 50:60] = rng.integers(5, 30, (10, 10))
    yield "object", big
    yield "uniform8bit", rng.integers(0, 256, (64, 64)).astype(np.float32)


@pytest.mark.parametrize("mode", ["public", "public-default"])
@pytest.mark.parametrize("name, delta", list(_delta_cases()), ids=lambda x: x if isinstance(x, str) else "")
def test_public_changed_matches_the_scripts_round_trips(mode, name, delta, tmp_path):
    res = public_changed(delta, mode)
    expected = public_script_changed(delta, mode == "public", tmp_path)
    np.testing.assert_array_equal(res.changed, expected)


def test_default_path_marks_small_changes_and_constant_masks_read_as_unchanged():
    delta = np.zeros((96, 128), np.float32)
    delta[30:70, 40:90] = 200.0
    delta[0:20, 0:20] = 3.0
    small = public_changed(delta, "public-default")
    large = public_changed(delta, "public")
    assert large.changed[30:70, 40:90].all() and not large.changed[:20, :20].any()
    assert not small.changed[30:70, 40:90].any() and small.changed[:20, :20].all()
    # Everything below the split: "im < t" is all True, saved all white, read as nothing changed.
    assert not public_changed(np.full((8, 8), 20, np.float32), "public-default").changed.any()


def test_compat_mode_names():
    assert check_compat(True) == "public" and check_compat(None) is None and check_compat(False) is None
    assert check_compat("public-default") == "public-default"
    with pytest.raises(InputError, match="public-default"):
        check_compat("8bit")


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
    for f in (depth_delta, public_delta):
        with pytest.raises(InputError):
            f(pre, post)
