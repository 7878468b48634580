"""Structural axis: retention, Hungarian matching, sim^v cases, modes, and the GPU
path against a brute-force numpy oracle on random masks."""
from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.structural import (
    StructuralView,
    match,
    structural_summary,
    structural_view,
)
from r360gpu.probes.base import MaskSet

H, W = 10, 20


def _m(*boxes):
    m = np.zeros((H, W), bool)
    for r0, r1, c0, c1 in boxes:
        m[r0:r1, c0:c1] = True
    return m


# Atoms: X = 40 px, Y = 40 px, e = 2 px.
X, Y, E = (0, 4, 0, 10), (4, 8, 0, 10), (8, 9, 0, 2)
TARGET = _m(X, Y, E)  # 82 px


def test_hungarian_beats_greedy(ctx):
    a = np.stack([_m(X, Y), _m(Y, E)])  # A0 = X∪Y (80), A1 = Y∪e (42)
    b = np.stack([_m(X, Y, E), _m(X)])  # B0 = X∪Y∪e (82), B1 = X (40)
    # IoU matrix [[80/82, 40/80], [42/82, 0]]: greedy takes 80/82 first and then 0,
    # the optimal assignment pairs (A0, B1) and (A1, B0).
    v = structural_view(a, b, TARGET, mode="reference", ctx=ctx)
    expected = (40 / 80 + 42 / 82) / 2
    greedy = (80 / 82 + 0.0) / 2
    assert v.sim_sam == pytest.approx(expected, abs=1e-15)
    assert v.sim_sam > greedy
    assert v.pairs == ((0, 1), (1, 0))
    assert v.pair_iou == pytest.approx((0.5, 42 / 82))
    assert (v.n_a, v.n_b) == (2, 2)


def test_both_empty_is_one_and_one_empty_is_zero(ctx):
    outside = np.zeros((1, H, W), bool)
    outside[0, 9, 10:20] = True  # no overlap with the target: not retained
    both = structural_view(outside, None, TARGET, mode="reference", ctx=ctx)
    assert both.sim_sam == 1.0 and (both.n_a, both.n_b) == (0, 0) and both.pairs == ()
    one = structural_view(np.stack([TARGET]), outside, TARGET, mode="reference", ctx=ctx)
    assert one.sim_sam == 0.0 and (one.n_a, one.n_b) == (1, 0)
    other = structural_view(MaskSet.empty(H, W), np.stack([TARGET]), TARGET, mode="reference_free", ctx=ctx)
    assert other.sim_sam == 0.0 and other.s_str == 1.0


def test_more_masks_on_one_side_are_penalised(ctx):
    a = np.stack([_m(X)])
    b = np.stack([_m(X), _m(Y), _m(X, Y, E)])
    v = structural_view(a, b, TARGET, mode="reference", ctx=ctx)
    assert (v.n_a, v.n_b) == (1, 3)
    assert v.sim_sam == pytest.approx(1.0 / 3, abs=1e-15)  # X matched with X, divided by max(1, 3)
    assert v.pairs == ((0, 0),)


def test_identical_renders(ctx):
    masks = np.stack([_m(X), _m(Y), _m(X, Y)])
    ref = structural_view(masks, masks.copy(), TARGET, mode="reference", ctx=ctx)
    assert ref.sim_sam == 1.0 and ref.s_str == 1.0
    free = structural_view(masks, masks.copy(), TARGET, mode="reference_free", ctx=ctx)
    assert free.sim_sam == 1.0 and free.s_str == 0.0


def test_retention_threshold_is_iou_at_least_0_1(ctx):
    target = _m((0, 10, 0, 10))  # 100 px
    ten = _m((0, 1, 0, 10))  # IoU 10 / 100 = 0.1: retained
    nine = _m((0, 1, 0, 9))  # IoU 0.09: dropped
    big_outside = _m((0, 10, 5, 20))  # 50 px in, union 200: IoU 0.25, retained though 2/3 lie outside
    a = np.stack([nine, ten, big_outside, nine])
    v = structural_view(a, np.stack([ten]), target, mode="reference", ctx=ctx)
    assert v.retained_a == (1, 2) and v.retained_b == (0,)
    assert v.pairs == ((1, 0),)  # original indices, not positions in the retained list
    assert v.sim_sam == 0.5


def test_empty_target_excluded_unless_asked(ctx):
    empty = np.zeros((H, W), bool)
    v = structural_view(np.stack([TARGET]), np.stack([TARGET]), empty, mode="reference_free", ctx=ctx)
    assert v.empty_target and v.sim_sam == 1.0 and (v.n_a, v.n_b) == (0, 0)
    w = structural_view(np.stack([_m(X)]), np.stack([_m(X, Y)]), TARGET, mode="reference_free", ctx=ctx)
    s = structural_summary([v, w])
    assert (s.n_views, s.n_scored, s.n_empty_target) == (2, 1, 1)
    assert s.sim_sam == 0.5 and s.s_str == 0.5
    t = structural_summary([v, w], include_empty_targets=True)
    assert t.sim_sam == 0.75 and t.s_str == 0.25


def test_summary_modes(ctx):
    views = [
        structural_view(np.stack([_m(X)]), np.stack([_m(X, Y)]), TARGET, mode="reference", ctx=ctx),  # 0.5
        structural_view(np.stack([_m(X)]), np.stack([_m(X)]), TARGET, mode="reference", ctx=ctx),  # 1
    ]
    s = structural_summary(views)
    assert s.mode == "reference" and s.sim_sam == 0.75 and s.s_str == 0.75
    free = structural_view(np.stack([_m(X)]), None, TARGET, mode="reference_free", ctx=ctx)
    with pytest.raises(InputError, match="mix modes"):
        structural_summary(views + [free])
    e = structural_summary([], mode="reference_free")
    assert e.sim_sam is None and e.s_str is None
    with pytest.raises(InputError):
        structural_summary([])
    with pytest.raises(InputError):
        structural_view(None, None, TARGET, mode="ref", ctx=ctx)


def test_match_on_matrices():
    rows, cols, total = match(np.array([[0.9, 0.8], [0.8, 0.1]]))
    assert total == pytest.approx(1.6) and list(zip(rows, cols)) == [(0, 1), (1, 0)]
    assert match(np.zeros((0, 3)))[2] == 0.0
    _, _, t = match(np.array([[0.2, 0.7, 0.1]]))  # rectangular: best single match
    assert t == 0.7


def test_matching_uses_scipys_own_assignment_without_importing_scipy_optimize():
    """match() solves with scipy's compiled linear_sum_assignment loaded on its own (the package
    import costs a run 0.2-0.6 s): the same function's answers, and scipy.optimize not imported."""
    import subprocess
    import sys

    code = ("import sys, numpy as np; from r360gpu.metrics.structural import linear_sum_assignment, match; "
            "f = linear_sum_assignment(); print(f.__module__, 'scipy.optimize' in sys.modules); "
            "print(match(np.array([[0.5, 0.5], [0.5, 0.5], [0.2, 0.9]]))[:2])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[0] == "scipy.optimize._lsap False"
    from scipy.optimize import linear_sum_assignment as official

    from r360gpu.metrics.structural import linear_sum_assignment

    rng = np.random.default_rng(0)
    for shape in [(1, 1), (2, 3), (4, 2), (5, 5)]:
        for m in (rng.uniform(size=shape), np.round(rng.uniform(size=shape), 1), np.full(shape, 0.5)):  # ties too
            got, want = linear_sum_assignment()(m, maximize=True), official(m, maximize=True)
            assert all(np.array_equal(g, w) and g.dtype == w.dtype for g, w in zip(got, want))
            assert all(np.array_equal(g, w) for g, w in zip(match(m)[:2], want))


def _brute_force(a, b, target, thr=0.1):
    def iou(p, q):
        u = np.logical_or(p, q).sum()
        return np.logical_and(p, q).sum() / u if u else 0.0

    ka = [i for i in range(len(a)) if iou(a[i], target) >= thr]
    kb = [j for j in range(len(b)) if iou(b[j], target) >= thr]
    if not ka and not kb:
        return 1.0
    if not ka or not kb:
        return 0.0
    mat = np.array([[iou(a[i], b[j]) for j in kb] for i in ka])
    n, m = mat.shape
    if n <= m:
        best = max(sum(mat[i, p[i]] for i in range(n)) for p in itertools.permutations(range(m), n))
    else:
        best = max(sum(mat[p[j], j] for j in range(m)) for p in itertools.permutations(range(n), m))
    return best / max(n, m)


@pytest.mark.parametrize("shape", [(11, 13), (40, 70)])
def test_random_masks_match_brute_force_oracle(ctx, small_ctx, shape):
    rng = np.random.default_rng(shape[1])
    h, w = shape
    for trial in range(6):
        target = np.zeros(shape, bool)
        target[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4] = True

        def blobs(k):
            out = np.zeros((k, h, w), bool)
            for i in range(k):
                r0, c0 = rng.integers(0, h - 2), rng.integers(0, w - 2)
                out[i, r0 : rng.integers(r0 + 1, h + 1), c0 : rng.integers(c0 + 1, w + 1)] = True
            return out

        a, b = blobs(rng.integers(0, 6)), blobs(rng.integers(0, 6))
        c = small_ctx if trial % 2 else ctx
        v = structural_view(a, b, target, mode="reference", ctx=c)
        assert v.sim_sam == pytest.approx(_brute_force(a, b, target), abs=1e-12)


def test_record_round_trip(ctx):
    a = np.stack([_m(X, Y), _m(Y, E)])
    b = np.stack([_m(X, Y, E), _m(X)])
    v = structural_view(MaskSet(a, None, "sam2"), MaskSet(b, None, "sam2"), TARGET, mode="reference_free", ctx=ctx)
    assert v.probe == "sam2"
    d = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    assert StructuralView.from_dict(d) == v
    d["mode"] = "other"
    with pytest.raises(InputError):
        StructuralView.from_dict(d)


def test_size_mismatch_names_view(ctx):
    with pytest.raises(InputError, match="view v1"):
        structural_view(np.zeros((1, H, W + 1), bool), None, TARGET, mode="reference", view="v1", ctx=ctx)
