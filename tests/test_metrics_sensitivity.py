"""Robustness sweeps: ξ sweep from stored IoUs, mask erosion / dilation, and the
boundary table against recomputing every axis from scratch with the perturbed mask."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.geometric import acc_depth, acc_depth_view
from r360gpu.metrics.semantic import semantic_summary, semantic_view
from r360gpu.metrics.sensitivity import (
    BOUNDARY_OFFSETS,
    BoundaryInput,
    BoundarySweep,
    boundary_label,
    boundary_sensitivity,
    perturb_mask,
    threshold_sweep,
)
from r360gpu.kernels import mask_iou as K
from r360gpu.metrics.structural import retained, structural_from_ious, structural_summary, structural_view


def _disc_offsets(r):
    """Offsets (dy, dx) of OpenCV's (2r+1) elliptical element."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    return [(dy - r, dx - r) for dy, dx in zip(*np.nonzero(k))]


def _morph_oracle(m, r, dilate):
    """Dilation / erosion by shifting; outside the image counts as target for erosion."""
    h, w = m.shape
    pad = np.pad(m, r, constant_values=not dilate)
    out = np.zeros_like(m) if dilate else np.ones_like(m)
    for dy, dx in _disc_offsets(r):
        s = pad[r + dy : r + dy + h, r + dx : r + dx + w]
        out = (out | s) if dilate else (out & s)
    return out


def test_labels():
    assert [boundary_label(o) for o in BOUNDARY_OFFSETS] == ["E15", "E10", "E5", "Original", "D5", "D10", "D15"]


def test_perturb_mask_hand_cases():
    m = np.zeros((60, 60), bool)
    m[20:40, 20:40] = True
    e5 = perturb_mask(m, -5)
    expect = np.zeros_like(m)
    expect[25:35, 25:35] = True  # a disc of radius 5 fits only 5 px away from every edge
    np.testing.assert_array_equal(e5, expect)
    dot = np.zeros((41, 41), bool)
    dot[20, 20] = True
    d10 = perturb_mask(dot, 10)
    assert d10.sum() == cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (21, 21)).sum()
    assert d10[20, 10] and d10[20, 30] and d10[10, 20] and not d10[20, 9] and not d10[10, 10]
    np.testing.assert_array_equal(perturb_mask(m, 0), m)
    assert perturb_mask(m, -15).sum() == 0  # 20 px wide object is eroded away


@pytest.mark.parametrize("r", [5, 10, 15])
def test_perturb_mask_matches_shift_oracle(r):
    rng = np.random.default_rng(r)
    m = np.zeros((50, 61), bool)
    for _ in range(4):
        y, x = rng.integers(0, 50), rng.integers(0, 61)
        m[max(0, y - 8) : y + 8, max(0, x - 12) : x + 12] = True
    m[:, :3] = True  # touches the border: erosion does not eat in from outside
    np.testing.assert_array_equal(perturb_mask(m, r), _morph_oracle(m, r, True))
    np.testing.assert_array_equal(perturb_mask(m, -r), _morph_oracle(m, r, False))


def test_perturb_mask_rejects_fractions():
    with pytest.raises(InputError):
        perturb_mask(np.ones((5, 5), bool), 2.5)


def test_threshold_sweep_from_stored_values(ctx):
    t = np.zeros((10, 10), bool)
    t[:, :5] = True  # 50 px
    views = []
    for cols in (1, 2, 4, 5):  # IoU_post 0.2, 0.4, 0.8, 1.0
        p = np.zeros_like(t)
        p[:, :cols] = True
        views.append(semantic_view(t, p, t, ctx=ctx))
    assert [v.iou_post for v in views] == [0.2, 0.4, 0.8, 1.0]
    assert threshold_sweep(views) == {0.3: 0.25, 0.5: 0.5, 0.7: 0.5, 0.9: 0.75}
    assert threshold_sweep(views, [0.0, 1.0]) == {0.0: 0.0, 1.0: 0.75}
    assert threshold_sweep([]) == {0.3: None, 0.5: None, 0.7: None, 0.9: None}


def _scene(rng, n_views=3, h=48, w=64):
    """Views of a box object with predictions, mask sets and depths."""
    out = []
    for i in range(n_views):
        t = np.zeros((h, w), bool)
        r0, c0 = 10 + i, 14 + 2 * i
        t[r0 : r0 + 22, c0 : c0 + 26] = True
        pre = t[None].copy()
        post = np.zeros((2, h, w), bool)
        post[0, r0 : r0 + 22, c0 : c0 + 8 + 4 * i] = True  # part of the object still found
        post[1, 0:6, 0:10] = True  # a false detection elsewhere
        a = np.zeros((3, h, w), bool)
        a[0] = t
        a[1, r0 : r0 + 11, c0 : c0 + 26] = True
        a[2, r0 - 4 : r0 + 26, c0 - 6 : c0 + 30] = True
        b = np.zeros((2, h, w), bool)
        b[0, r0 + 2 : r0 + 22, c0 : c0 + 24] = True
        b[1, r0 + 11 : r0 + 22, c0 : c0 + 26] = True
        d_pre = np.full((h, w), 4.0, np.float32) + rng.normal(0, 0.01, (h, w)).astype(np.float32)
        d_pre[t] = 2.0
        d_post = d_pre.copy()
        d_post[r0 : r0 + 22, c0 : c0 + 20] = 4.0
        out.append(dict(target=t, pre=pre, post=post, a=a, b=b, depths=(d_pre, d_post), view=f"v{i}"))
    return out


def test_boundary_table_equals_recomputing_each_axis(ctx):
    rng = np.random.default_rng(7)
    views = _scene(rng)
    geos = [acc_depth_view(*v["depths"], v["target"], ctx=ctx) for v in views]
    inputs = [
        BoundaryInput(v["target"], v["pre"], v["post"], v["a"], v["b"], g if i % 2 else v["depths"], v["view"])
        for i, (v, g) in enumerate(zip(views, geos))
    ]
    offs = (-10, -5, 0, 5, 15)
    table = boundary_sensitivity(inputs, BoundarySweep(structural_mode="reference", offsets=offs, xis=(0.3, 0.5)),
                                 ctx=ctx)
    assert table.labels == ("E10", "E5", "Original", "D5", "D15")
    for k, o in enumerate(offs):
        ts = [perturb_mask(v["target"], o) for v in views]
        sem = semantic_summary([semantic_view(v["pre"], v["post"], t, ctx=ctx) for v, t in zip(views, ts)], (0.3, 0.5))
        st = structural_summary(
            [structural_view(v["a"], v["b"], t, mode="reference", ctx=ctx) for v, t in zip(views, ts)]
        )
        geo, _ = acc_depth([acc_depth_view(*v["depths"], t, ctx=ctx) for v, t in zip(views, ts)])
        assert table.rows["iou_pre"][k] == sem.iou_pre
        assert table.rows["iou_post"][k] == sem.iou_post
        assert table.rows["iou_drop"][k] == sem.iou_drop
        assert table.rows["acc_seg@0.3"][k] == sem.acc_seg[0.3]
        assert table.rows["acc_seg@0.5"][k] == sem.acc_seg[0.5]
        assert table.rows["sim_sam"][k] == pytest.approx(st.sim_sam, abs=1e-15)
        assert table.rows["s_str"][k] == pytest.approx(st.s_str, abs=1e-15)
        assert table.rows["acc_depth"][k] == pytest.approx(geo, abs=1e-15)
    assert table.row("acc_depth")["Original"] == pytest.approx(acc_depth(geos)[0], abs=1e-15)
    assert table.n_scored == {"semantic": [3] * 5, "geometric": [3] * 5, "structural": [3] * 5}
    d = json.loads(json.dumps(table.to_dict(), allow_nan=False))
    assert d["labels"][2] == "Original" and d["mode"] == "reference"


def test_boundary_hand_values(ctx):
    t = np.zeros((60, 60), bool)
    t[20:40, 20:40] = True  # 400 px; E5 leaves 100 px
    d_pre = np.full((60, 60), 5.0, np.float32)
    d_pre[t] = 2.0
    d_post = d_pre.copy()
    d_post[20:40, 20:30] = 5.0  # left half of the object removed from the depth
    inp = BoundaryInput(t, pred_pre=t, pred_post=None, geometric=(d_pre, d_post))
    table = boundary_sensitivity([inp], BoundarySweep(offsets=(-5, 0)), ctx=ctx)
    assert table.row("iou_pre") == {"E5": 0.25, "Original": 1.0}
    assert table.row("iou_post") == {"E5": 0.0, "Original": 0.0}
    assert table.row("acc_seg@0.3") == {"E5": 1.0, "Original": 1.0}
    assert table.row("acc_depth") == {"E5": 0.5, "Original": 0.5}
    assert "sim_sam" not in table.rows and table.mode is None


def test_eroded_away_target_is_excluded(ctx):
    small = np.zeros((40, 40), bool)
    small[10:16, 10:16] = True  # gone after erosion by 5
    big = np.zeros((40, 40), bool)
    big[5:35, 5:35] = True
    depth = np.full((40, 40), 3.0, np.float32)
    inputs = [
        BoundaryInput(small, small, None, small[None], small[None], (depth, depth * 1.5)),
        BoundaryInput(big, big, big, big[None], None, (depth, depth)),
    ]
    table = boundary_sensitivity(inputs, BoundarySweep(structural_mode="reference_free", offsets=(-5, 0)), ctx=ctx)
    assert table.n_scored == {"semantic": [1, 2], "geometric": [1, 2], "structural": [1, 2]}
    assert table.row("acc_seg@0.3") == {"E5": 0.0, "Original": 0.5}
    # Reference-free: the big view has one retained mask against none -> sim 0, s_str 1.
    assert table.row("s_str") == {"E5": 1.0, "Original": 0.5}
    kept = boundary_sensitivity(
        inputs, BoundarySweep(geometric=False, structural_mode="reference_free", offsets=(-5,),
                              include_empty_targets=True), ctx=ctx
    )
    assert kept.n_scored == {"semantic": [2], "structural": [2]}
    assert kept.rows["acc_seg@0.3"] == [0.5]  # the empty view counts as "not detected"


def test_missing_inputs_are_errors_not_empty_predictions(ctx):
    t = np.ones((12, 12), bool)
    with pytest.raises(InputError, match="view x.*pred_pre, pred_post"):
        boundary_sensitivity([BoundaryInput(t, view="x")], ctx=ctx)
    with pytest.raises(InputError, match="geometric"):
        boundary_sensitivity([BoundaryInput(t, None, None, view="x")], ctx=ctx)
    with pytest.raises(InputError, match="masks_b"):
        boundary_sensitivity(
            [BoundaryInput(t, masks_a=None)],
            BoundarySweep(semantic=False, geometric=False, structural_mode="reference"), ctx=ctx
        )
    with pytest.raises(InputError, match="GeometricView or a"):
        boundary_sensitivity([BoundaryInput(t, None, None, geometric=t)], ctx=ctx)
    with pytest.raises(InputError):
        boundary_sensitivity([BoundaryInput(t)], BoundarySweep(semantic=False, geometric=False, structural_mode="both"),
                             ctx=ctx)


def test_structural_rows_equal_the_whole_iou_matrix_way(ctx):
    # Many masks, retained at some offsets and not at others: the sweep's IoUs between retained masks
    # (computed for the masks retained at any offset) equal, bit for bit, the entries of the whole matrix.
    rng = np.random.default_rng(12)
    h, w = 60, 90
    t = np.zeros((h, w), bool)
    t[15:45, 20:70] = True
    a = np.zeros((25, h, w), bool)
    b = np.zeros((20, h, w), bool)
    for stack in (a, b):
        for k in range(stack.shape[0]):
            r0, c0 = rng.integers(0, h - 5), rng.integers(0, w - 5)
            stack[k, r0 : r0 + rng.integers(3, 40), c0 : c0 + rng.integers(3, 60)] = True
    offs = (-12, -6, 0, 6, 12)
    for mode in ("reference", "reference_free"):
        table = boundary_sensitivity([BoundaryInput(t, masks_a=a, masks_b=b)],
                                     BoundarySweep(semantic=False, geometric=False, structural_mode=mode, offsets=offs),
                                     ctx=ctx)
        whole = K.mask_iou(a, b, ctx=ctx).iou
        kept = []
        for k, o in enumerate(offs):
            m = perturb_mask(t, o)
            keep_a, keep_b = retained(K.iou_with_target(a, m, ctx=ctx)), retained(K.iou_with_target(b, m, ctx=ctx))
            kept.append((len(keep_a), len(keep_b)))
            sv = structural_from_ious(keep_a, keep_b, whole[np.ix_(keep_a, keep_b)], area_target=int(m.sum()), mode=mode)
            s = structural_summary([sv], mode=mode)
            assert table.rows["sim_sam"][k] == s.sim_sam and table.rows["s_str"][k] == s.s_str
        assert len(set(kept)) > 2  # the retained sets differ between offsets
