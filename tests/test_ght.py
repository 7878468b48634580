"""Tests of r360gpu.metrics.ght: brute-force objective, Otsu / MET / percentile limits, edge cases."""
from __future__ import annotations

import math
from fractions import Fraction

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from r360gpu.errors import InputError
from r360gpu.metrics.ght import GhtResult, ght, threshold_value

FLOOR = 1e-30


def brute_force_scores(n, x, nu, tau, kappa, omega):
    """f0 + f1 of every split, from explicit per-class sums (two-pass scatter).

    Written independently of the module: loops over bins, class mean first and
    then the scatter sum n (x - mu)^2, no cumulative sums.
    """
    n = [float(c) for c in n]
    x = [float(v) for v in x]
    length = len(n)
    out = []
    for i in range(length - 1):
        classes = ((range(0, i + 1), omega), (range(i + 1, length), 1.0 - omega))
        weights = [max(FLOOR, sum(n[j] for j in idx)) for idx, _ in classes]
        total = 0.0
        for (idx, om), w in zip(classes, weights):
            mean = sum(n[j] * x[j] for j in idx) / w
            scatter = sum(n[j] * (x[j] - mean) ** 2 for j in idx)
            p = w / (weights[0] + weights[1])
            v = max(FLOOR, (p * nu * tau**2 + scatter) / (p * nu + w))
            total += -scatter / v - w * math.log(v) + 2.0 * (w + kappa * om) * math.log(w)
        out.append(total)
    return np.array(out)


def check_against_brute_force(n, x, nu, tau, kappa, omega):
    res = ght(n, x, nu=nu, tau=tau, kappa=kappa, omega=omega)
    xs = np.arange(len(n), dtype=float) if x is None else np.asarray(x, dtype=float)
    ref = brute_force_scores(n, xs, nu, tau, kappa, omega)
    assert isinstance(res, GhtResult)
    assert res.scores.shape == (len(n) - 1,)
    assert np.all(np.isfinite(res.scores)) and math.isfinite(res.threshold)
    tol = 1e-9 * max(1.0, float(np.max(np.abs(ref))))
    np.testing.assert_allclose(res.scores, ref, rtol=0, atol=tol)
    # Every split the module calls best is best by the brute force too.
    chosen = res.scores == res.scores.max()
    assert np.all(ref[chosen] >= ref.max() - 2 * tol)
    assert res.threshold == pytest.approx(float(np.mean(xs[:-1][chosen])), abs=1e-12 * (1 + abs(xs).max()))
    # Where the brute-force maximum is clearly unique, the thresholds agree exactly.
    order = np.sort(ref)
    if len(ref) == 1 or order[-1] - order[-2] > 4 * tol:
        assert res.threshold == xs[int(np.argmax(ref))]


# --- (a) the objective, against an explicit brute-force evaluation ---------------------------

@settings(max_examples=150, deadline=None)
@given(
    n=st.lists(st.integers(0, 2000), min_size=2, max_size=40),
    nu=st.sampled_from([0.0, 1.0, 1000.0]) | st.floats(0.0, 1e4),
    tau=st.sampled_from([0.0, 300.0]) | st.floats(0.0, 1e3),
    kappa=st.sampled_from([0.0]) | st.floats(0.0, 1e3),
    omega=st.floats(0.0, 1.0),
)
def test_objective_matches_brute_force_integer_positions(n, nu, tau, kappa, omega):
    check_against_brute_force(n, None, nu, tau, kappa, omega)


@settings(max_examples=60, deadline=None)
@given(
    n=st.lists(st.floats(0.0, 50.0), min_size=2, max_size=30),
    steps=st.lists(st.floats(0.01, 3.0), min_size=30, max_size=30),
    offset=st.floats(-100.0, 100.0),
    nu=st.floats(1.0, 1e4),
    tau=st.floats(0.5, 50.0),
    kappa=st.floats(0.0, 100.0),
    omega=st.floats(0.0, 1.0),
)
def test_objective_matches_brute_force_real_positions(n, steps, offset, nu, tau, kappa, omega):
    x = offset + np.cumsum(steps[: len(n)])
    check_against_brute_force(n, x, nu, tau, kappa, omega)


@pytest.mark.parametrize("seed", range(6))
def test_objective_matches_brute_force_on_256_bin_histograms(seed):
    rng = np.random.default_rng(seed)
    # Bimodal |dD|-like data: many small changes and a cluster of large ones.
    small = np.abs(rng.normal(0, rng.uniform(2, 20), rng.integers(1000, 20000)))
    large = rng.normal(rng.uniform(80, 220), rng.uniform(3, 30), rng.integers(10, 5000))
    values = np.clip(np.concatenate([small, large]), 0, 255)
    n, _ = np.histogram(values, bins=256, range=(0, 255))
    check_against_brute_force(n, None, 1000.0, 300.0, 0.0, 0.0)


def test_integer_and_float_histograms_agree():
    rng = np.random.default_rng(7)
    n = rng.integers(0, 500, 256)
    a, b = ght(n), ght(n.astype(np.float64))
    assert a.threshold == b.threshold
    np.testing.assert_array_equal(a.scores, b.scores)


# --- degenerate histograms and ties ---------------------------------------------------------

def test_empty_histogram_ties_everywhere():
    res = ght(np.zeros(256))
    assert res.threshold == 127.0
    assert np.all(res.scores == res.scores[0])


@pytest.mark.parametrize("k", [0, 1, 100, 254, 255])
def test_single_occupied_bin_ties_everywhere(k):
    n = np.zeros(256)
    n[k] = 12345
    res = ght(n)
    assert res.threshold == 127.0
    assert np.all(np.isfinite(res.scores))


def test_length_one_histogram_has_no_split():
    res = ght([42.0], x=[3.5])
    assert res.threshold == 3.5
    assert res.scores.shape == (0,)


def test_length_two_histogram_has_one_split():
    assert ght([3, 5], x=[10.0, 20.0]).threshold == 10.0


@pytest.mark.parametrize("params", [dict(), dict(nu=0.0, tau=0.0), dict(nu=1e30, tau=1e-6)])
def test_empty_plateau_ties_to_its_midpoint(params):
    # Splits 10..199 give the same two classes, so they tie exactly.
    n = np.zeros(256)
    n[10], n[200] = 5000, 7000
    res = ght(n, **params)
    assert res.threshold == np.mean(np.arange(10, 200))
    assert np.all(res.scores[10:200] == res.scores[10])


def test_strong_prior_prefers_one_class_on_small_histograms():
    # With the reference prior (nu=1000, tau=300 bins) and only 1200 pixels, one
    # wide class beats two zero-scatter classes: the best splits leave a class
    # empty (positions 0..9 and 200..254), and their mean is the threshold.
    n = np.zeros(256)
    n[10], n[200] = 500, 700
    res = ght(n)
    empty_class = np.r_[0:10, 200:255]
    assert res.threshold == pytest.approx(np.mean(empty_class), abs=1e-12)


@pytest.mark.parametrize(
    "hist, x",
    [
        (np.zeros((4, 4)), None),
        (np.array([]), None),
        ([1.0, -1.0, 2.0], None),
        ([1.0, np.nan, 2.0], None),
        ([1.0, np.inf, 2.0], None),
        (["a", "b"], None),
        ([1, 2, 3], [0.0, 1.0]),
        ([1, 2, 3], [0.0, 2.0, 1.0]),
        ([1, 2, 3], [0.0, np.nan, 1.0]),
    ],
)
def test_bad_histograms_raise_input_error(hist, x):
    with pytest.raises(InputError):
        ght(hist, x)


@pytest.mark.parametrize(
    "params",
    [dict(nu=-1.0), dict(tau=-1.0), dict(kappa=-0.5), dict(omega=1.5), dict(omega=-0.1),
     dict(nu=float("inf")), dict(tau=float("nan"))],
)
def test_bad_parameters_raise_input_error(params):
    with pytest.raises(InputError):
        ght([1, 2, 3, 4], **params)


def test_overflowing_objective_raises_instead_of_nan():
    with pytest.raises(InputError):
        ght([1e300, 1e300, 1e300], x=[0.0, 1e200, 2e200], nu=0.0, tau=0.0)
    with pytest.raises(InputError):
        ght([1.0, 2.0, 3.0], nu=1e300, tau=1e300)


# --- (b) the Otsu limit, against OpenCV -----------------------------------------------------

def otsu_between_class(img: np.ndarray, t: float) -> Fraction:
    """Exact between-class scatter w0 w1 (mu0 - mu1)^2 (times N^2) of the split img <= t."""
    v = img.astype(np.int64).ravel()
    lower = v <= t
    w0, w1 = int(lower.sum()), int((~lower).sum())
    if w0 == 0 or w1 == 0:
        return Fraction(0)
    s0, s1 = int(v[lower].sum()), int(v[~lower].sum())
    return Fraction(w0 * w1) * (Fraction(s0, w0) - Fraction(s1, w1)) ** 2


def otsu_test_images():
    rng = np.random.default_rng(2020)
    images = []
    for i in range(40):
        h, w = rng.integers(5, 64, 2)
        kind = i % 5
        if kind == 0:
            img = rng.integers(0, 256, (h, w))
        elif kind == 1:
            a = rng.normal(rng.uniform(20, 100), rng.uniform(2, 25), (h, w))
            b = rng.normal(rng.uniform(120, 240), rng.uniform(2, 25), (h, w))
            img = np.where(rng.random((h, w)) < rng.uniform(0.05, 0.95), a, b)
        elif kind == 2:
            img = rng.choice(rng.integers(0, 256, rng.integers(2, 5)), (h, w))
        elif kind == 3:
            yy, xx = np.mgrid[0:h, 0:w]
            img = 255.0 * (xx + yy) / max(1, h + w - 2) + rng.normal(0, 4, (h, w))
        else:
            img = rng.exponential(rng.uniform(5, 60), (h, w))
        images.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    images.append(np.full((9, 11), 77, np.uint8))  # one gray level: every split ties
    images.append(np.array([[0, 255]], np.uint8))
    return images


@pytest.mark.parametrize("index", range(42))
def test_ght_otsu_limit_matches_opencv(index):
    img = otsu_test_images()[index]
    t_cv, _ = cv2.threshold(img, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    hist = np.bincount(img.ravel(), minlength=256)
    # Barron's Otsu limit: nu -> inf, tau -> 0 (his unit test uses nu=1e30, tau=1e-6).
    t_ght = ght(hist, nu=1e30, tau=1e-6, kappa=0.0, omega=0.0).threshold
    # cv2 puts pixels <= t in class 0 and takes the first strict maximum; GHT's split
    # at position t also puts bins <= t in class 0 but averages tied positions.  Both
    # thresholds must give the same partition, or partitions with (near) equal
    # between-class scatter, i.e. a genuine tie.
    same = np.array_equal(img > t_cv, img > t_ght)
    if not same:
        a, b = otsu_between_class(img, t_cv), otsu_between_class(img, t_ght)
        assert abs(a - b) <= Fraction(1, 10**9) * max(a, b), (t_cv, t_ght, float(a), float(b))


def test_ght_otsu_limit_agrees_exactly_on_most_images():
    agree = 0
    images = otsu_test_images()
    for img in images:
        t_cv, _ = cv2.threshold(img, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        t_ght = ght(np.bincount(img.ravel(), minlength=256), nu=1e30, tau=1e-6).threshold
        agree += np.array_equal(img > t_cv, img > t_ght)
    # Only the single-gray-level image (cv2 -> 0, GHT -> 127) may split differently.
    assert agree >= len(images) - 1


# --- (c) the Minimum Error Thresholding and percentile limits -------------------------------

def met_loss(n):
    """Kittler-Illingworth MET loss per split (Barron eq.), from explicit sums."""
    n = [float(c) for c in n]
    out = []
    for i in range(len(n) - 1):
        ell = 1.0
        for idx in (range(0, i + 1), range(i + 1, len(n))):
            w = max(FLOOR, sum(n[j] for j in idx))
            mean = sum(n[j] * j for j in idx) / w
            var = sum(n[j] * (j - mean) ** 2 for j in idx) / w
            ell += w * math.log(max(FLOOR, var)) - 2.0 * w * math.log(w)
        out.append(ell)
    return np.array(out)


@pytest.mark.parametrize("seed", range(8))
def test_ght_with_nu_zero_is_minimum_error_thresholding(seed):
    rng = np.random.default_rng(100 + seed)
    length = int(rng.integers(3, 80))
    n = rng.integers(1, 300, length)  # every bin occupied: no class is ever empty
    res = ght(n, nu=0.0, tau=0.0, kappa=0.0, omega=0.5)
    ell = met_loss(n)
    # Barron: with nu = 0 the GHT score is 1 - sum(n) - ell.  At the two end
    # splits one class is a single bin with zero scatter; its variance is floored
    # to 1e-30 in both, but GHT's -d/v term is then 0 instead of -w.
    expected = 1.0 - n.sum() - ell
    expected[0] += n[0]
    expected[-1] += n[-1]
    np.testing.assert_allclose(res.scores, expected, rtol=1e-10, atol=1e-6)
    order = np.sort(expected)
    if order[-1] - order[-2] > 1e-6:
        assert res.threshold == float(np.argmax(expected))
    if 0 < np.argmin(ell) < len(ell) - 1 and np.sort(ell)[1] - ell.min() > 1e-6:
        assert res.threshold == float(np.argmin(ell))


@pytest.mark.parametrize("seed", range(5))
def test_ght_with_huge_kappa_is_weighted_percentile(seed):
    rng = np.random.default_rng(200 + seed)
    n = rng.integers(0, 100, 64).astype(float)
    omega = float(rng.uniform(0.05, 0.95))
    res = ght(n, kappa=1e30, omega=omega)
    w0 = np.maximum(FLOOR, np.cumsum(n)[:-1])
    w1 = np.maximum(FLOOR, n.sum() - np.cumsum(n)[:-1])
    h = -omega * np.log(w0 / n.sum()) - (1 - omega) * np.log(w1 / n.sum())
    order = np.sort(h)
    if order[1] - order[0] > 1e-9:
        assert res.threshold == float(np.argmin(h))


# --- threshold_value: bin index -> data value ----------------------------------------------

@pytest.mark.parametrize("seed", range(4))
def test_threshold_value_is_upper_edge_of_the_last_class_zero_bin(seed):
    rng = np.random.default_rng(300 + seed)
    values = rng.exponential(rng.uniform(0.01, 5.0), 20000)
    lo, hi = float(values.min()), float(values.max())
    edges = np.histogram_bin_edges(values, bins=256, range=(lo, hi))
    index = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, 255)
    for t in range(255):
        xi = threshold_value(t, lo, hi)
        off_edge = np.abs(values - xi) > 1e-9 * (hi - lo)
        np.testing.assert_array_equal((values > xi)[off_edge], (index > t)[off_edge])


def test_threshold_value_special_cases():
    assert threshold_value(127.0, 2.5, 2.5) == 2.5
    assert threshold_value(0, 0.0, 256.0) == 1.0
    assert threshold_value(254, 0.0, 256.0) == 255.0
    assert threshold_value(10.5, 0.0, 1.0) == pytest.approx(
        0.5 * (threshold_value(10, 0.0, 1.0) + threshold_value(11, 0.0, 1.0)))
    assert threshold_value(1, 0.0, 4.0, n_bins=4) == 2.0


@pytest.mark.parametrize(
    "args",
    [(255.0, 0.0, 1.0), (-1.0, 0.0, 1.0), (1.0, 2.0, 1.0), (1.0, 0.0, float("inf")),
     (float("nan"), 0.0, 1.0)],
)
def test_threshold_value_rejects_bad_arguments(args):
    with pytest.raises(InputError):
        threshold_value(*args)


def test_threshold_value_rejects_too_few_bins():
    with pytest.raises(InputError):
        threshold_value(0.0, 0.0, 1.0, n_bins=1)
