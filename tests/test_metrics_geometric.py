"""Geometric axis per view: GPU path against a numpy + GHT oracle; compat path; exclusions."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.metrics.compat import public_changed, public_delta
from r360gpu.metrics.geometric import GhtParams, acc_depth, acc_depth_view
from r360gpu.metrics.ght import ght

from oracles import depth_change_oracle


def _object_scene(rng, h=60, w=80):
    """A box in front of a wall; 'removal' pushes most box pixels back to the wall."""
    pre = np.full((h, w), 5.0, np.float32) + rng.normal(0, 0.01, (h, w)).astype(np.float32)
    mask = np.zeros((h, w), bool)
    mask[20:40, 30:60] = True
    pre[mask] = 2.0
    post = pre.copy()
    post[20:40, 30:55] = 5.0  # five columns of the object stay
    return pre, post, mask


def test_float_mode_matches_oracle(ctx):
    rng = np.random.default_rng(0)
    pre, post, mask = _object_scene(rng)
    v = acc_depth_view(pre, post, mask, ctx=ctx)
    _, lo, hi, hist, _, _, _ = depth_change_oracle(pre, post, mask, 0)
    split = ght(hist).threshold
    _, _, _, _, changed, n_in, n_m = depth_change_oracle(pre, post, mask, split)
    assert v.split == split and v.mode == "float" and not v.excluded
    np.testing.assert_array_equal(v.changed, changed)
    assert v.acc_depth == n_in / n_m
    assert abs(v.acc_depth - 25 / 30) < 1e-9  # exactly the removed columns
    assert lo < v.threshold < hi


@pytest.mark.parametrize("compat, mode", [(True, "public"), ("public", "public"), ("public-default", "public-default")])
def test_compat_modes_use_the_public_rule(ctx, compat, mode):
    rng = np.random.default_rng(1)
    pre, post, mask = _object_scene(rng)
    v = acc_depth_view(pre, post, mask, compat=compat)
    ref = public_changed(public_delta(pre, post), mode)
    np.testing.assert_array_equal(v.changed, ref.changed)
    assert v.mode == mode and v.threshold == ref.threshold
    if mode == "public":
        assert abs(v.acc_depth - 25 / 30) < 1e-9
    else:
        # The default path thresholds raw |dD| (0 and 3 here) with "< t": both levels lie below
        # the split, the mask is all True, and the scripts save it as an all-white "no change".
        assert v.threshold > 3 and not v.changed.any() and v.acc_depth == 0.0


def test_empty_mask_is_excluded_not_scored(ctx):
    rng = np.random.default_rng(2)
    pre, post, _ = _object_scene(rng)
    v = acc_depth_view(pre, post, np.zeros_like(pre, bool), ctx=ctx)
    assert v.excluded and v.acc_depth is None
    w = acc_depth_view(pre, post, np.ones_like(pre, bool), ctx=ctx)
    mean, n_excl = acc_depth([v, w])
    assert n_excl == 1 and mean == w.acc_depth
    assert acc_depth([v]) == (None, 1)


def test_identical_renders_change_nothing(ctx):
    rng = np.random.default_rng(3)
    pre, _, mask = _object_scene(rng)
    v = acc_depth_view(pre, pre, mask, ctx=ctx)
    assert v.acc_depth == 0.0 and not v.changed.any()


def test_ght_parameters_are_passed_through(ctx):
    rng = np.random.default_rng(4)
    pre, post, mask = _object_scene(rng)
    a = acc_depth_view(pre, post, mask, ctx=ctx)
    b = acc_depth_view(pre, post, mask, ctx=ctx, ght_params=GhtParams(nu=0.0, tau=0.0))
    _, _, _, hist, _, _, _ = depth_change_oracle(pre, post, mask, 0)
    assert b.split == ght(hist, nu=0.0, tau=0.0).threshold
    assert a.split == ght(hist).threshold


@pytest.mark.parametrize("compat", [False, "public", "public-default"])
def test_a_see_through_hole_is_counted_and_changes_nothing_else(ctx, compat):
    """Pixels of M with no depth after removal (a see-through hole) are counted per view, in every
    mode, as the kernels' oracle counts them; acc_depth, the threshold and the changed mask are
    those of the same view measured before the count existed (the count is new, nothing else)."""
    from r360gpu.metrics.geometric import acc_depth_views

    from oracles import no_depth_oracle

    rng = np.random.default_rng(3)
    pre, post, mask = _object_scene(rng)
    holed = post.copy()
    holed[22:30, 55:63] = 0.0  # 8 x 5 of them inside M (columns 55..59), 3 columns outside
    holed[31, 31] = np.nan
    if compat:
        pre, holed = np.round(pre * 40).astype(np.uint8), np.round(np.nan_to_num(holed) * 40).astype(np.uint8)
    v = acc_depth_view(pre, holed, mask, compat=compat, ctx=ctx)
    n_holes = 8 * 5 + 1  # the NaN is level 0 in the 8-bit images
    assert v.n_no_depth_in_mask == no_depth_oracle(holed, mask) == n_holes
    assert v.summary()["n_no_depth_in_mask"] == n_holes
    assert acc_depth_views(pre, [holed, pre], mask, compat=compat, ctx=ctx)[0].summary() == v.summary()
    assert acc_depth_view(pre, holed, np.zeros_like(mask), compat=compat, ctx=ctx).n_no_depth_in_mask == 0
    if not compat:  # dD is 0 there by the missing-depth rule: never "changed"
        assert not v.changed[22:30, 55:63].any()
