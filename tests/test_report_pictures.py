"""Panels, contact sheets and plots: sizes, content, determinism."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.report.contact_sheets import (
    _resize_rgb,
    BACKGROUND_RGB,
    CHANGED_OUTSIDE_RGB,
    _legend_rows,
    balanced_columns,
    legend_items,
    view_numbers,
    CHANGED_IN_TARGET_RGB,
    MISSED_IN_TARGET_RGB,
    NO_DEPTH_IN_TARGET_RGB,
    SEMANTIC_RGB,
    TARGET_RGB,
    THRESHOLD_RGB,
    as_rgb8,
    changed_panel,
    contact_sheet,
    depth_change_panel,
    mask_colors,
    mask_overlay,
    no_depth_fraction,
    rgb8_at,
    sheet_image,
    view_contact_sheet,
    SheetView,
    view_panels,
)
from r360gpu.report.plots import axes_overview_png, view_axes_plot, view_axes_png, view_series

from report_fake import VIEWS, images, view_record

H, W = 120, 160


def _count(img, rgb):
    return int(np.all(img == np.array(rgb, np.uint8), axis=2).sum())


@pytest.fixture(scope="module")
def scene():
    yy, xx = np.mgrid[0:H, 0:W]
    target = (np.abs(yy - 60) < 30) & (np.abs(xx - 80) < 40)
    delta = np.where(target, 1.0, 0.05) + 0.01 * (xx / W)
    rgb = np.dstack([xx / W, yy / H, np.full((H, W), 0.5)]).astype(np.float32)
    return rgb, target, delta


def test_as_rgb8_conversions():
    assert as_rgb8(np.ones((2, 3), bool)).tolist() == [[[255] * 3] * 3] * 2
    f = as_rgb8(np.array([[[0.0, 0.5, 2.0]]], np.float32))
    assert f.dtype == np.uint8 and f.tolist() == [[[0, 128, 255]]]
    assert as_rgb8(np.zeros((4, 5, 4), np.uint8)).shape == (4, 5, 3)
    odd = np.array([[np.nan, np.inf, -np.inf, -0.0, 0.5, 1.5, -2.0, 127.5 / 255]])
    for dt in (np.float32, np.float64):  # non-finite as 0 / 1 / 0, then clipped, scaled and rounded
        assert as_rgb8(odd.astype(dt))[0, :, 0].tolist() == [0, 255, 0, 0, 128, 255, 0, 128]
    with pytest.raises(InputError, match="expected an"):
        as_rgb8(np.zeros((4, 5, 2)))


@pytest.mark.parametrize("shape,width", [((120, 160, 3), 100), ((97, 203, 3), 64), ((1, 1, 3), 40),
                                         ((31, 17), 240), ((40, 60, 4), 60), ((5, 7, 1), 3)])
def test_rgb8_at_resizes_floats_first(shape, width):
    """Floats are averaged then quantised once (within one level of quantising first); uint8 images,
    upscales and non-finite floats give exactly what as_rgb8-then-resize gives."""
    rng = np.random.default_rng(sum(shape) + width)
    f = rng.random(shape).astype(np.float32)
    q_first = _resize_rgb(as_rgb8(f), width)
    got = rgb8_at(f, width)
    assert got.dtype == np.uint8 and got.shape == q_first.shape
    want = as_rgb8(_resize_rgb(np.asarray(f)[..., :3] if f.ndim == 3 and f.shape[2] == 4 else f, width))
    np.testing.assert_array_equal(got, want)
    assert np.abs(got.astype(int) - q_first).max() <= 1
    if width >= shape[1]:  # nearest upscale: the same pixels either way
        np.testing.assert_array_equal(got, q_first)
    u8 = as_rgb8(f)
    np.testing.assert_array_equal(rgb8_at(u8, width), _resize_rgb(u8, width))
    np.testing.assert_array_equal(rgb8_at(f.astype(np.float64), width), got)
    bad = f.copy()
    bad.flat[:: max(1, bad.size // 7)] = [np.nan, np.inf, -np.inf, 2.0, -1.0, 0.5]  # flat assignment cycles
    np.testing.assert_array_equal(rgb8_at(bad, width), _resize_rgb(as_rgb8(bad), width))
    with pytest.raises(InputError, match="expected an"):
        rgb8_at(np.zeros((4, 5, 2), np.float32), 3)


def test_depth_change_panel_shows_non_finite_as_zero():
    rng = np.random.default_rng(3)
    d = rng.random((50, 80)).astype(np.float32)
    holes = d.copy()
    holes[::7, ::5] = np.nan
    holes[3, 3], holes[9, 40] = np.inf, -np.inf
    zeros = d.copy()
    zeros[~np.isfinite(holes)] = 0
    np.testing.assert_array_equal(depth_change_panel(holes, 0.3, width=64), depth_change_panel(zeros, 0.3, width=64))
    np.testing.assert_array_equal(depth_change_panel(-d.astype(np.float64), 0.3, width=64),
                                  depth_change_panel(d, 0.3, width=64))


def test_depth_change_panel_marks_threshold(scene):
    _, _, delta = scene
    p = depth_change_panel(delta, 0.5, width=200)
    assert p.dtype == np.uint8 and p.shape == (150 + 26, 200, 3)  # heat map 200 x 150, then the bar strip
    heat = p[:150]
    assert heat.std() > 20  # not blank
    # the threshold tick is drawn in the bar strip, about half-way along the bar
    cols = np.nonzero(np.all(p[150:] == np.array(THRESHOLD_RGB, np.uint8), axis=2).any(axis=0))[0]
    assert cols.size and abs(cols.mean() - 0.5 / delta.max() * 199) < 3
    assert _count(depth_change_panel(delta, None, width=200), THRESHOLD_RGB) == 0
    np.testing.assert_array_equal(p, depth_change_panel(delta, 0.5, width=200))
    flat = depth_change_panel(np.zeros((10, 10)), 0.0, width=40)
    assert flat.shape == (40 + 26, 40, 3)
    with pytest.raises(InputError):
        depth_change_panel(np.zeros((2, 2, 2)), 0.1)


def test_changed_panel_colours_and_outline(scene):
    _, target, delta = scene
    changed = delta > 0.5
    changed[60:, :] = False  # half of the target missed
    p = changed_panel(changed, target, width=W)
    assert p.shape == (H, W, 3)
    assert _count(p, TARGET_RGB) > 200  # the outline of the 80 x 60 target
    inside_changed = _count(p, CHANGED_IN_TARGET_RGB)
    missed = _count(p, MISSED_IN_TARGET_RGB)
    # interior pixels split about evenly between counted and missed (the outline covers the border)
    assert inside_changed > 1000 and missed > 1000 and abs(inside_changed - missed) < 200
    with pytest.raises(InputError, match="changed mask is"):
        changed_panel(changed[:10], target)


def test_no_depth_in_the_target_has_its_own_colour_count_and_legend(scene):
    pre, target, delta = scene
    changed = delta > 0.5
    changed[60:, :] = False  # half of the target not changed ...
    no_depth = np.zeros_like(changed)
    no_depth[75:, :] = True  # ... of which a part has no depth after removal (a see-through hole)
    p = changed_panel(changed, target, width=W, no_depth=no_depth)
    holes, missed = _count(p, NO_DEPTH_IN_TARGET_RGB), _count(p, MISSED_IN_TARGET_RGB)
    assert holes > 100 and missed > 100
    assert holes + missed == _count(changed_panel(changed, target, width=W), MISSED_IN_TARGET_RGB)
    t = target != 0
    assert no_depth_fraction(no_depth, target) == float((no_depth & t).sum()) / t.sum()
    assert no_depth_fraction(no_depth, np.zeros_like(t)) is None
    with pytest.raises(InputError, match="no-depth mask is"):
        changed_panel(changed, target, no_depth=no_depth[:10])
    panels = view_panels(SheetView(pre=pre, post=pre, target=target, changed=changed, no_depth=no_depth), width=W)
    title = [t for t, _ in panels if t.startswith("changed")][0]
    assert f"no depth in {no_depth_fraction(no_depth, target):.0%} of M" in title
    assert any(c == NO_DEPTH_IN_TARGET_RGB for c, _ in legend_items(panels))
    plain = view_panels(SheetView(pre=pre, post=pre, target=target, changed=changed, no_depth=np.zeros_like(t)),
                        width=W)
    assert not any(c == NO_DEPTH_IN_TARGET_RGB for c, _ in legend_items(plain))  # no hole: no legend entry


def test_mask_overlay_is_seeded_and_outlined(scene):
    rgb, target, _ = scene
    masks = np.stack([target, np.roll(target, 30, axis=1)])
    a = mask_overlay(rgb, masks, width=W, seed=3)
    np.testing.assert_array_equal(a, mask_overlay(rgb, masks, width=W, seed=3))
    assert not np.array_equal(a, mask_overlay(rgb, masks, width=W, seed=4))
    assert not np.array_equal(a, as_rgb8(rgb))
    sem = mask_overlay(rgb, target, width=W, color=SEMANTIC_RGB)
    assert _count(sem, SEMANTIC_RGB) > 200  # its outline
    with_t = mask_overlay(rgb, np.roll(target, 30, axis=1), width=W, color=SEMANTIC_RGB, target=target)
    assert _count(with_t, TARGET_RGB) > 200
    assert mask_colors(5, 1).shape == (5, 3) and mask_colors(0).shape == (0, 3)
    assert np.array_equal(mask_colors(5, 1), mask_colors(5, 1))
    with pytest.raises(InputError, match="overlay masks are"):
        mask_overlay(rgb, masks[:, :10], width=W)


@pytest.mark.parametrize("seed", range(6))
def test_mask_overlay_blend_is_the_plain_per_mask_blend(seed):
    """The overlay blends each mask (in order) into the float32 panel as
    (1 - alpha) * pixel + alpha * colour, rounded once at the end; it works on each mask's bounding
    box only, which must give exactly the whole-image blend (outlines drawn on both alike)."""
    from r360gpu.report.contact_sheets import _outline, resize_mask, _resize_rgb

    rng = np.random.default_rng(seed)
    h, w = rng.integers(1, 90, 2)
    rgb = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    masks = rng.random((4, h, w)) < rng.uniform(0, 1, (4, 1, 1))
    masks[0] = False  # an empty mask
    if seed % 2:
        masks[1] = True  # a full one
    width = int(rng.integers(16, 200))
    got = mask_overlay(rgb, masks, width=width, seed=seed, alpha=0.45)
    img = _resize_rgb(rgb, width).astype(np.float32)
    size = (img.shape[1], img.shape[0])
    cols = mask_colors(4, seed)
    small = [resize_mask(m, size) for m in masks]
    for m, col in zip(small, cols):
        img[m] = (1.0 - 0.45) * img[m] + 0.45 * col.astype(np.float32)
    want = np.rint(img).astype(np.uint8)
    for m, col in zip(small, cols):
        _outline(want, m, tuple(int(c) for c in col))
    np.testing.assert_array_equal(got, want)


def test_contact_sheet_layout_and_png(tmp_path, scene):
    rgb, target, delta = scene
    panels = [("a", rgb), ("b", target), ("c", depth_change_panel(delta, 0.5, 100)), ("d", rgb), ("e", rgb)]
    img = sheet_image(panels, columns=3, panel_width=100, title="sheet")
    # 3 columns of 100 px plus 4 px gaps; rows: title line + 2 rows of (title strip + panel)
    assert img.shape[1] == 4 + 3 * 104
    path = contact_sheet(tmp_path / "sub" / "s.png", panels, columns=3, panel_width=100, title="sheet")
    back = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert back is not None and back.shape == img.shape
    np.testing.assert_array_equal(cv2.cvtColor(back, cv2.COLOR_BGR2RGB), img)
    first = path.read_bytes()
    contact_sheet(path, panels, columns=3, panel_width=100, title="sheet")
    assert path.read_bytes() == first  # deterministic bytes
    with pytest.raises(InputError, match="at least one panel"):
        sheet_image([])
    with pytest.raises(InputError, match="at least 16 px"):
        sheet_image(panels, panel_width=4)


def test_view_contact_sheet_from_fake_view(tmp_path):
    pre, post, ref, d_pre, d_post, t = images("room", "ghost", "01")
    panels = view_panels(SheetView(pre=pre, post=post, ref=ref, target=t, delta=np.abs(d_pre - d_post),
                                   threshold=0.25, semantic_post=t, structural=[("masks", post, np.stack([t, ~t]))]),
                         width=96)
    assert [p[0] for p in panels] == ["I_pre (target outlined)", "I_post (target outlined)", "I_ref",
                                      "|dD|, t_depth (GHT) = 0.25", "changed |dD| > t_depth (legend below)",
                                      "semantic probe on I_post", "masks"]
    assert all(p[1].shape[1] == 96 for p in panels)
    rec = view_record("room", "ghost", "01").to_dict()
    path = view_contact_sheet(tmp_path / "v.png", pre=pre, post=post, ref=ref, target=t,
                              delta=np.abs(d_pre - d_post), threshold=0.25, semantic_post=t, width=96, title="v",
                              record=rec)
    img = cv2.imread(str(path))
    # 6 panels -> 2 rows of 3 (balanced, no lone panel)
    assert img.shape[1] == 4 + 3 * 100
    assert img.std() > 20
    lines = view_numbers(rec)
    assert lines == ["semantic: builtin-appearance: IoU 0.87 -> 0.10 (not found at xi=0.3)",
                     "acc_depth 0.250 (t_depth 0.260) | sim_SAM 0.600 [builtin-graphseg] | "
                     "PSNR 22.0 dB, SSIM 0.700, LPIPS 0.300"]
    # the numbers and the legend are drawn: the sheet is taller than the same sheet without them
    plain = sheet_image(panels[:6], panel_width=96, title="v")
    assert img.shape[0] == plain.shape[0] + 2 * 18 + len(_legend_rows(legend_items(panels[:6]), img.shape[1] - 8)) * 18 + 4
    # every colour of the changed panel is explained, dark red and light grey included
    texts = [t for _, t in legend_items(panels)]
    for needle in ("dark red", "light grey", "yellow", "dark grey", "green outline", "magenta", "cyan tick"):
        assert any(needle in t for t in texts), needle
    colours = {c for c, _ in legend_items(panels)}
    assert {MISSED_IN_TARGET_RGB, CHANGED_OUTSIDE_RGB, CHANGED_IN_TARGET_RGB, BACKGROUND_RGB} <= colours


@pytest.mark.parametrize("n, cols", [(1, 1), (4, 4), (5, 5), (6, 3), (7, 4), (8, 4), (9, 5), (10, 5), (11, 4)])
def test_balanced_columns_leave_no_lone_panel(n, cols):
    assert balanced_columns(n) == cols
    last = n - (-(-n // cols) - 1) * cols
    assert n == 1 or last >= 2


def test_view_series_and_plot(tmp_path):
    recs = [view_record("garden", "blurry", v) for v in VIEWS]
    s = view_series(recs)
    assert s["names"] == list(VIEWS) and s["excluded"] == [False, False, True]
    assert s["mode"] == "reference"
    assert np.isnan(s["acc_depth"][2]) and s["acc_depth"][:2] == [0.95, 0.95]
    assert s["iou_post"]["builtin-appearance"][:2] == pytest.approx([0.2, 0.3])
    assert np.isnan(s["iou_post"]["builtin-appearance"][2]) and np.isnan(s["sim_sam"]["builtin-graphseg"][2])
    assert s["sim_sam"]["builtin-graphseg"][:2] == [0.5, 0.5]
    d = view_series([r.to_dict() for r in recs])  # dicts and records both accepted
    assert (d["names"], d["excluded"], d["iou_post"], d["sim_sam"]) == (s["names"], s["excluded"], s["iou_post"],
                                                                         s["sim_sam"])
    png = view_axes_png(recs, title="garden / blurry")
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (300, 800, 3) and img.std() > 10
    assert png == view_axes_png([r.to_dict() for r in recs], title="garden / blurry")  # deterministic
    assert b"tEXt" not in png and b"iTXt" not in png  # no metadata (no version, no timestamp)
    # marking the excluded view changes the picture
    plain = [view_record("room", "blurry", v) for v in VIEWS]
    assert view_axes_png(plain) != view_axes_png(recs)
    path = view_axes_plot(tmp_path / "p" / "plot.png", recs)
    assert path.read_bytes() == view_axes_png(recs)


def test_axes_overview_png():
    overall = {"a": {"s_sem": 0.9, "s_geo": 0.3, "s_str": 0.6, "rqs": 0.55},
               "b": {"s_sem": 0.7, "s_geo": None, "s_str": 0.5, "rqs": None}}
    png = axes_overview_png(overall, title="t")
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[0] == 280 and img.std() > 10
    assert png == axes_overview_png(overall, title="t")


@pytest.mark.parametrize("n_lines", [0, 2])
@pytest.mark.parametrize("width", [64, 128])
def test_sheet_panel_cuts_out_one_panel(n_lines, width):
    from r360gpu.report.contact_sheets import sheet_panel

    rng = np.random.default_rng(3)
    panels = [(f"p{i}", rng.integers(0, 250, (30 + 4 * i, 40, 3)).astype(np.uint8)) for i in range(7)]
    sheet = sheet_image(panels, panel_width=width, title="t", lines=["a line"] * n_lines)
    got = sheet_panel(sheet, 1, n_lines=n_lines)
    expected = cv2.resize(panels[1][1], (width, round(34 * width / 40)), interpolation=cv2.INTER_NEAREST)
    assert got is not None and np.array_equal(got, expected)
    assert sheet_panel(sheet, 9, n_lines=n_lines) is None  # only 4 columns
    assert sheet_panel(np.full((200, 300, 3), 255, np.uint8), 1, n_lines=0) is None  # not a sheet


def test_panels_of_the_same_arrays_are_made_once_per_view_and_equal_fresh_ones(scene):
    """A view's sheets share I_pre, I_ref and the probes' readings on them: with a memo those
    panels are made once (same objects) and equal the panels made without it."""
    rgb, target, delta = scene
    rng = np.random.default_rng(0)
    ref = np.clip(rgb + 0.1, 0, 1)
    ref_masks = rng.random((3,) + target.shape) < 0.3
    from r360gpu.util.memo import ByIdentity

    memo = ByIdentity()
    sheets = []
    for k in range(3):  # three methods of one view
        post = np.clip(rgb * (0.5 + 0.1 * k), 0, 1)
        view = SheetView(pre=rgb, post=post, target=target, ref=ref, delta=delta, threshold=0.5,
                         semantic_pre=target, semantic_post=np.roll(target, k, axis=1),
                         structural=[("masks on I_ref", ref, ref_masks), ("masks on I_post", post, ref_masks[:k + 1])])
        got = view_panels(view, width=120, memo=memo)
        fresh = view_panels(view, width=120)
        assert [t for t, _ in got] == [t for t, _ in fresh]
        for (_, a), (_, b) in zip(got, fresh):
            np.testing.assert_array_equal(a, b)
        sheets.append(dict(got))
    for title in ("I_pre (target outlined)", "I_ref", "semantic probe on I_pre", "masks on I_ref"):
        assert sheets[0][title] is sheets[1][title] is sheets[2][title]
    for title in ("I_post (target outlined)", "semantic probe on I_post", "masks on I_post"):
        assert sheets[0][title] is not sheets[1][title]
    other = view_panels(SheetView(pre=rgb, post=rgb, target=target), width=100, memo=memo)  # another width: anew
    assert other[0][1].shape[1] == 100
