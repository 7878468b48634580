"""Semantic axis: hand-computed IoU_pre / IoU_post / iou_drop / acc_seg, edge cases,
and the GPU path against a numpy oracle on random masks."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.semantic import (
    XI_SWEEP,
    SemanticView,
    acc_seg,
    semantic_summary,
    semantic_view,
)
from r360gpu.probes.base import SemanticPrediction

H, W = 12, 16


def _box(r0, r1, c0, c1):
    m = np.zeros((H, W), bool)
    m[r0:r1, c0:c1] = True
    return m


TARGET = _box(2, 7, 2, 8)  # 5 x 6 = 30 px


def test_hand_computed_view(ctx):
    # Two overlapping instances on I_pre: union [2:7, 2:10] = 40 px, 30 of them in M.
    pre = np.stack([_box(2, 7, 2, 6), _box(2, 7, 4, 10)])
    # On I_post one instance outside M and one covering 12 px of M.
    post = np.stack([_box(0, 2, 0, 4), _box(5, 7, 2, 8)])
    v = semantic_view(pre, post, TARGET, ctx=ctx)
    assert v.iou_pre == 30 / 40
    assert v.iou_post == 12 / (30 + 8)  # union: M plus the 8 px outside
    assert v.iou_drop == pytest.approx(0.75 - 12 / 38, abs=1e-15)
    assert (v.area_target, v.area_pred_pre, v.area_pred_post) == (30, 40, 20)
    assert (v.inter_pre, v.inter_post) == (30, 12)
    assert (v.n_instances_pre, v.n_instances_post) == (2, 2)
    assert v.detected_at() == {0.3: True, 0.5: False, 0.7: False, 0.9: False}
    assert not v.empty_target


def test_no_detection_means_empty_mask_and_iou_zero(ctx):
    for none in (None, SemanticPrediction.empty(H, W, "gsam2"), np.zeros((0, H, W), bool)):
        v = semantic_view(TARGET, none, TARGET, ctx=ctx)
        assert v.iou_pre == 1.0 and v.iou_post == 0.0 and v.iou_drop == 1.0
        assert v.n_instances_post == 0 and v.area_pred_post == 0
        assert not any(v.detected_at().values())


def test_prediction_objects_and_single_masks(ctx):
    pred = SemanticPrediction(np.stack([_box(2, 7, 2, 5), _box(2, 7, 5, 8)]), [0.9, 0.8], ["sofa", "sofa"], "gsam2")
    v = semantic_view(pred, _box(2, 7, 2, 5), TARGET, ctx=ctx)  # an (H, W) mask is one instance
    assert v.probe == "gsam2"
    assert v.iou_pre == 1.0 and v.iou_post == 0.5
    assert v.detected(0.5) and not v.detected(0.7)  # IoU exactly at ξ counts as detected


def test_empty_target_scored_zero_and_excluded_by_default(ctx):
    empty = np.zeros((H, W), bool)
    v = semantic_view(_box(0, 3, 0, 3), _box(0, 3, 0, 3), empty, ctx=ctx)
    assert v.empty_target and v.iou_pre == 0.0 and v.iou_post == 0.0 and v.iou_drop == 0.0
    both_empty = semantic_view(None, None, empty, ctx=ctx)
    assert both_empty.iou_pre == 0.0 and both_empty.empty_target
    good = semantic_view(TARGET, None, TARGET, ctx=ctx)
    s = semantic_summary([v, good])
    assert (s.n_views, s.n_scored, s.n_empty_target) == (2, 1, 1)
    assert s.iou_drop == 1.0 and s.s_sem == 1.0
    # The reference code's convention: the empty view is scored as "not detected".
    r = semantic_summary([v, good], include_empty_targets=True)
    assert r.n_scored == 2 and r.iou_drop == 0.5 and r.s_sem == 1.0 and r.iou_pre == 0.5
    only = semantic_summary([v])
    assert only.n_scored == 0 and only.s_sem is None and only.iou_drop is None


def test_summary_over_views_hand_values(ctx):
    views = [
        semantic_view(TARGET, _box(2, 7, 2, 8), TARGET, ctx=ctx),  # post 1.0
        semantic_view(TARGET, _box(2, 7, 2, 5), TARGET, ctx=ctx),  # post 0.5
        semantic_view(_box(2, 7, 2, 5), _box(2, 3, 2, 8), TARGET, ctx=ctx),  # pre 0.5, post 0.2
        semantic_view(None, None, TARGET, ctx=ctx),  # 0, 0
    ]
    assert [v.iou_post for v in views] == [1.0, 0.5, 0.2, 0.0]
    s = semantic_summary(views, XI_SWEEP)
    assert s.iou_pre == pytest.approx((1 + 1 + 0.5 + 0) / 4)
    assert s.iou_post == pytest.approx(1.7 / 4)
    assert s.iou_drop == pytest.approx((0 + 0.5 + 0.3 + 0) / 4)
    assert s.acc_seg == {0.3: 0.5, 0.5: 0.5, 0.7: 0.75, 0.9: 0.75}
    assert s.s_sem == 0.5
    # 0.3 is always reported, whatever thresholds are asked for.
    assert set(semantic_summary(views, [0.6]).acc_seg) == {0.3, 0.6}


def test_acc_seg_function():
    assert acc_seg([0.1, 0.3, 0.29999, 0.9]) == 0.5
    assert acc_seg([0.1, 0.3], 0.9) == 1.0
    assert acc_seg([], 0.3) is None
    with pytest.raises(InputError):
        acc_seg([0.1], 1.5)
    with pytest.raises(InputError):
        acc_seg([0.1], -0.1)


def test_bad_inputs_name_the_view(ctx):
    with pytest.raises(InputError, match="view 007"):
        semantic_view(np.zeros((1, H + 1, W), bool), None, TARGET, view="007", ctx=ctx)
    with pytest.raises(InputError, match="target"):
        semantic_view(None, None, np.zeros((2, H, W), bool), ctx=ctx)
    with pytest.raises(InputError, match="NaN"):
        semantic_view(np.full((H, W), np.nan), None, TARGET, ctx=ctx)


def _oracle(pre, post, target):
    def iou(a, b):
        u = np.logical_or(a, b).sum()
        return np.logical_and(a, b).sum() / u if u else 0.0

    up, uq = pre.any(0), post.any(0)
    return iou(up, target), iou(uq, target)


@pytest.mark.parametrize("shape", [(9, 13), (33, 70), (64, 32)])
def test_random_masks_match_numpy_oracle(ctx, small_ctx, shape):
    rng = np.random.default_rng(sum(shape))
    for trial in range(4):
        target = rng.random(shape) < 0.3
        pre = rng.random((rng.integers(0, 5), *shape)) < 0.15
        post = rng.random((rng.integers(0, 5), *shape)) < 0.15
        c = small_ctx if trial % 2 else ctx
        v = semantic_view(pre, post, target, ctx=c)
        e_pre, e_post = _oracle(pre, post, target)
        assert v.iou_pre == pytest.approx(e_pre, abs=1e-15)
        assert v.iou_post == pytest.approx(e_post, abs=1e-15)
        assert v.area_pred_pre == pre.any(0).sum() and v.area_target == target.sum()


def test_record_round_trip(ctx):
    v = semantic_view(np.stack([_box(2, 7, 2, 6)]), _box(5, 7, 2, 8), TARGET, ctx=ctx)
    d = json.loads(json.dumps(v.to_dict(), allow_nan=False))
    assert SemanticView.from_dict(d) == v
    assert d["detected"] == {"0.3": True, "0.5": False, "0.7": False, "0.9": False}
    with pytest.raises(InputError, match="iou_post"):
        SemanticView.from_dict({k: x for k, x in d.items() if k != "iou_post"})
