"""Axis association (Spearman raw / scene-centred with permutation p, Kendall tau) and tab:supp_axis_corr."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.stats import spearmanr

from r360gpu.aggregate import AXIS_PAIRS, axis_association, read_axes_csv, spearman_association

from remove360_paper import AXES_CSV, load


def _mc_tol(p: float, n: int, k: float = 4.0) -> float:
    return k * math.sqrt(max(p * (1 - p), 1e-4) / n)


def test_hand_computed_raw_centred_and_tau():
    # 2 scenes x 3 methods.  Raw ranks: a = 1..6, b = 1,2,3,6,5,4 -> sum d^2 = 8,
    # rho = 1 - 6*8 / (6*35) = 27/35.  Centred: a_c = (-.1, 0, .1) in both scenes,
    # b_c = (-.1, 0, .1) and (.1, 0, -.1): the tied centred ranks give rho_c = 0
    # exactly (only if 0.1-0.2 in one scene ties with 0.4-0.5 in the other despite
    # round-off).  Within-scene tau: +1 and -1 -> mean 0, sd (ddof=0) 1.
    a = [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]
    b = [[0.1, 0.2, 0.3], [0.6, 0.5, 0.4]]
    r = spearman_association(a, b, n_perm=200, seed=0)
    assert r.rho == pytest.approx(27 / 35, abs=1e-12)
    assert r.rho_centred == pytest.approx(0.0, abs=1e-12)
    assert r.p_centred == 1.0  # every permutation is at least as extreme as 0
    assert r.tau_mean == pytest.approx(0.0, abs=1e-12)
    assert r.tau_sd == pytest.approx(1.0)
    assert r.n_tau_scenes == 2


def test_permutation_p_against_exact_enumeration():
    # Exact p: enumerate all 6 x 6 within-scene relabellings of b with scipy.
    # Random values: no ties, so centring round-off cannot matter.
    rng = np.random.default_rng(4)
    a, b = rng.random((2, 3)), rng.random((2, 3))
    ac, bc = a - a.mean(1, keepdims=True), b - b.mean(1, keepdims=True)
    obs = spearmanr(ac.ravel(), bc.ravel()).statistic
    null = [spearmanr(ac.ravel(), np.concatenate([bc[0, list(p)], bc[1, list(q)]])).statistic
            for p in itertools.permutations(range(3)) for q in itertools.permutations(range(3))]
    exact = np.mean(np.abs(null) >= abs(obs) - 1e-12)
    n = 20000
    r = spearman_association(a, b, n_perm=n, seed=11)
    assert r.rho_centred == pytest.approx(obs, abs=1e-12)
    assert 0.0 < exact < 1.0
    assert abs(r.p_centred - exact) <= _mc_tol(exact, n)


def test_perfect_agreement_single_scene_p_value():
    # 1 scene, 4 methods: of the 24 relabellings only identity and reversal
    # reach |rho| = 1, so p = 2/24.
    r = spearman_association([[0.1, 0.2, 0.3, 0.4]], [[0.2, 0.4, 0.6, 0.8]], n_perm=20000, seed=2)
    assert r.rho == pytest.approx(1.0) and r.rho_centred == pytest.approx(1.0)
    assert abs(r.p_centred - 1 / 12) <= _mc_tol(1 / 12, 20000)
    assert r.tau_mean == pytest.approx(1.0) and r.tau_sd == 0.0


def test_constant_axis_and_one_method_are_undefined_not_errors():
    const = spearman_association([[0.5, 0.5], [0.5, 0.5]], [[0.1, 0.2], [0.3, 0.4]], n_perm=10)
    assert math.isnan(const.rho) and math.isnan(const.rho_centred) and math.isnan(const.p_centred)
    assert const.n_tau_scenes == 0 and math.isnan(const.tau_mean)
    one = spearman_association([[0.1], [0.5], [0.9]], [[0.2], [0.3], [0.8]], n_perm=10)
    assert one.rho == pytest.approx(1.0)
    assert math.isnan(one.rho_centred) and math.isnan(one.p_centred) and one.n_tau_scenes == 0


def test_scenes_with_undefined_tau_are_skipped():
    a = [[0.1, 0.2, 0.3], [0.5, 0.5, 0.5]]
    b = [[0.3, 0.2, 0.1], [0.1, 0.2, 0.3]]
    r = spearman_association(a, b, n_perm=10)
    assert r.n_tau_scenes == 1 and r.tau_mean == pytest.approx(-1.0) and r.tau_sd == 0.0


def test_deterministic_for_a_seed_and_validates_input():
    rng = np.random.default_rng(0)
    a, b = rng.random((5, 4)), rng.random((5, 4))
    assert spearman_association(a, b, seed=9) == spearman_association(a, b, seed=9)
    with pytest.raises(ValueError):
        spearman_association(a, b[:, :3])
    with pytest.raises(ValueError):
        spearman_association(a, b, n_perm=0)


@pytest.fixture(scope="module")
def paper():
    return read_axes_csv(AXES_CSV)


@pytest.fixture(scope="module")
def printed():
    return {row["pair"]: row for row in load("remove360_paper_axis_corr.csv")}


def test_tab_supp_axis_corr_raw_rho_and_within_scene_tau(paper, printed):
    """Raw Spearman rho (3 decimals) and within-scene Kendall tau-b mean +- sd (2 decimals, sd ddof=0)."""
    result = axis_association(paper, n_perm=10)
    assert list(result) == list(AXIS_PAIRS)
    for pair, r in result.items():
        row = printed[pair]
        assert row["rho"].matches(r.rho), (pair, r.rho)
        assert row["tau_mean"].matches(r.tau_mean), (pair, r.tau_mean)
        assert row["tau_sd"].matches(r.tau_sd), (pair, r.tau_sd)
        assert r.n_tau_scenes == 11


def test_tab_supp_axis_corr_scene_centred_rho(paper, printed):
    """Scene-centred rho: reproduced to within 0.0015, not always at the printed precision.

    Ours (exact ties kept): sem-geo -0.1302, sem-str 0.2984, geo-str -0.2206;
    printed -0.130, 0.299, -0.222.  The difference is tie handling, not the
    inputs: centring cells that are equal in exact arithmetic (e.g. two
    scenes' values both 0.04 above their scene mean) yields floats that differ
    by ~1e-16, and ranking those raw floats splits ties at random.  We round
    centred values to 12 decimals so exact ties stay ties; the unrounded
    computation below reproduces all three printed values, which shows where
    the 0.001 difference comes from.  The same holds for the IoU_drop vs
    acc_seg pair quoted in the text (0.7228 vs printed 0.722).
    """
    pairs = dict(AXIS_PAIRS, **{"iou_drop-sem": ("iou_drop", "s_sem")})
    for pair, (p, q) in pairs.items():
        a, b = getattr(paper, p), getattr(paper, q)
        ours = spearman_association(a, b, n_perm=10).rho_centred
        want = printed[pair]["rho_centred"]
        assert abs(ours - want.value) <= 0.0015, (pair, ours)
        if pair == "iou_drop-sem":
            assert printed[pair]["rho"].matches(spearman_association(a, b, n_perm=10).rho)
        unrounded = spearmanr((a - a.mean(1, keepdims=True)).ravel(), (b - b.mean(1, keepdims=True)).ravel())
        assert want.matches(unrounded.statistic), pair
    # the two pairs whose third decimal differs because of the tie handling
    result = axis_association(paper, n_perm=10)
    assert round(result["sem-str"].rho_centred, 3) == 0.298
    assert round(result["geo-str"].rho_centred, 3) == -0.221
    assert printed["sem-geo"]["rho_centred"].matches(result["sem-geo"].rho_centred)


@pytest.mark.parametrize("seed", [0, 1])
def test_tab_supp_axis_corr_permutation_p_within_noise(paper, printed, seed):
    """p of the scene-centred rho with 5,000 within-scene permutations.

    Both values are Monte-Carlo estimates from 5,000 permutations: their
    difference has standard error sqrt(2 p (1 - p) / 5000); we allow 4 of
    those plus half a unit of the printed last decimal (0.32 / 0.028 / 0.084).
    """
    n = 5000
    result = axis_association(paper, n_perm=n, seed=seed)
    for pair, r in result.items():
        want = printed[pair]["p_centred"]
        tol = math.sqrt(2) * _mc_tol(want.value, n) + want.half_ulp
        assert abs(r.p_centred - want.value) <= tol, (pair, r.p_centred, want.value)
