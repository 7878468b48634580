"""GPU overlays and composition of the viewer, against numpy and r360gpu's own kernels (lavapipe)."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.metrics.geometric import acc_depth_view
from r360gpu.render import Renderer
from viewer_fixtures import make_parts, orbit_cameras
from r360gpu.util.resize import resize_nearest
from r360gpu.viewer import colormaps
from r360gpu.viewer.compose import Compositor, fit_rect, layout, picture_at, wipe_fraction
from r360gpu.viewer.layers import PlaneImage
from r360gpu.viewer.live import delta_stats, live_axis
from r360gpu.viewer.overlays import (CHANGED_RGB, OverlayPass, OverlaySettings, overlay_reference, pack_mask,
                             read_picture)

W, H = 48, 36


def to8(c):
    return np.floor(np.clip(c, 0, 1) * 255 + 0.5).astype(np.uint8)


@pytest.fixture(scope="module")
def scenes(ctx):
    """pre / floaters rendered at one camera: device images and their numpy read-backs."""
    from r360gpu.io import Gaussians

    bg, ball, junk = make_parts(density=10)
    cam = orbit_cameras(4, W, H)[1]
    out = {}
    for name, g in (("pre", Gaussians.concat([bg, ball])), ("floaters", Gaussians.concat([bg, junk])),
                    ("ball", ball)):
        r = Renderer(g, ctx=ctx)
        dev = r.render_device(cam)
        out[name] = (PlaneImage(dev.buffer, W, H, dev.plane_stride, 4), dev.to_numpy(ctx))
    return cam, out


def run_overlay(ctx, img, settings, **kw):
    op = OverlayPass(ctx)
    pic = op.output_buffer(img.width, img.height)
    kw = {k: (op.upload_mask(v) if k == "mask" else v) for k, v in kw.items()}
    enc = ctx.encoder()
    op.record(enc, img, settings, pic, **kw)
    ctx.submit(enc)
    return read_picture(ctx, pic, img.width, img.height)


def test_plain_picture_is_the_render(ctx, scenes):
    _, s = scenes
    img, ref = s["pre"]
    got = run_overlay(ctx, img, OverlaySettings(outline=False))
    assert np.array_equal(got[..., :3], to8(ref.rgb)) and (got[..., 3] == 255).all()


def test_depth_overlay_matches_numpy(ctx, scenes):
    _, s = scenes
    img, ref = s["floaters"]
    op = OverlayPass(ctx)
    lo, hi = op.depth_range(img)
    valid = ref.depth > 0
    assert (lo, hi) == (ref.depth[valid].min(), ref.depth[valid].max())
    for cmap in colormaps.NAMES:
        st = OverlaySettings(depth=True, colormap=cmap, opacity=0.7, depth_range=(lo, hi))
        got = run_overlay(ctx, img, st)[..., :3].astype(int)
        want = to8(overlay_reference(ref.rgb, ref.depth, st)).astype(int)
        assert np.abs(got - want).max() <= 1, cmap


def test_delta_overlays_match_the_geometric_axis(ctx, scenes):
    _, s = scenes
    (pre, pre_np), (post, post_np), (_, ball_np) = s["pre"], s["floaters"], s["ball"]
    st = delta_stats(ctx, pre, post)
    mask = ball_np.alpha >= 0.5
    geo = acc_depth_view(pre_np.depth, post_np.depth, mask, ctx=ctx)
    assert (st.lo, st.hi, st.split) == (geo.lo, geo.hi, geo.split)
    assert st.threshold == pytest.approx(geo.threshold)
    # Changed mask alone, fully opaque: magenta exactly where the geometric axis says "changed".
    only = OverlaySettings(changed=True, opacity=1.0, delta=st)
    got = run_overlay(ctx, post, only, pre=pre)
    magenta = np.all(got[..., :3] == to8(np.array(CHANGED_RGB)), axis=-1)
    assert geo.changed.any() and np.array_equal(magenta, geo.changed)
    heat = OverlaySettings(delta_heat=True, changed=True, opacity=0.5, delta=st, heat_range=(0.0, st.hi))
    got = run_overlay(ctx, post, heat, pre=pre)[..., :3].astype(int)
    want = to8(overlay_reference(post_np.rgb, post_np.depth, heat, pre_depth=pre_np.depth)).astype(int)
    assert np.abs(got - want).max() <= 1
    # Without pre the |dD| overlays draw nothing.
    assert np.array_equal(run_overlay(ctx, post, heat)[..., :3], to8(post_np.rgb))
    live = live_axis(ctx, pre, post, mask, "evaluation")
    assert live.acc_depth == geo.acc_depth and live.n_mask == geo.n_mask


def test_outline_overlay(ctx, scenes):
    _, s = scenes
    img, ref = s["pre"]
    mask = s["ball"][1].alpha >= 0.5
    for r in (1, 2):
        st = OverlaySettings(outline=True, outline_px=r)
        got = run_overlay(ctx, img, st, mask=mask)[..., :3]
        want = to8(overlay_reference(ref.rgb, ref.depth, st, mask=mask))
        assert np.array_equal(got, want)
        edge = np.any(got != to8(ref.rgb), axis=-1)
        assert edge.any() and (edge <= mask).all()  # the outline lies on the mask's inner boundary


def test_pack_mask_and_resize():
    m = np.zeros((3, 11), bool)
    m[0, 0] = m[1, 2] = m[2, 10] = True
    words = pack_mask(m)
    bits = [(int(words[i // 32]) >> (i % 32)) & 1 for i in range(33)]
    assert [i for i, b in enumerate(bits) if b] == [0, 13, 32]
    a = np.arange(12).reshape(3, 4)
    assert np.array_equal(resize_nearest(a, (6, 8), axes=(0, 1)), np.repeat(np.repeat(a, 2, 0), 2, 1))
    assert resize_nearest(a, (3, 4), axes=(0, 1)) is a


def test_layout_arithmetic():
    assert fit_rect((0, 0, 200, 100), 1.0) == (50, 0, 100, 100)
    assert fit_rect((0, 0, 200, 100), None) == (0, 0, 200, 100)
    side = layout("side", 201, 100, aspect=4 / 3)
    (ax, ay, aw, ah), (bx, by, bw, bh) = side.rects
    assert (aw, ah) == (bw, bh) and ax + aw <= bx and side.render_size() == (aw, ah)
    wipe = layout("wipe", 300, 100, wipe=0.25)
    assert wipe.rects[0] == wipe.rects[1] and wipe.wipe_x == 75
    assert wipe_fraction(150, wipe) == 0.5
    assert picture_at(wipe, 10, 10) == 0 and picture_at(wipe, 200, 10) == 1
    assert picture_at(side, bx + 1, by + 1) == 1
    with pytest.raises(ValueError):
        layout("grid", 10, 10)


def _compose(ctx, fmt, lay, pictures, size):
    import wgpu

    from r360gpu.viewer.capture import read_texture

    tex = ctx.device.create_texture(size=(*size, 1), format=fmt,
                                    usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)
    enc = ctx.encoder()
    Compositor(ctx).record(enc, tex.create_view(), fmt, lay, pictures)
    ctx.submit(enc)
    return read_texture(ctx.device, tex)


def _picture(ctx, rgb):
    h, w = rgb.shape[:2]
    rgba = np.concatenate([rgb, np.full((h, w, 1), 255, np.uint8)], -1)
    return (ctx.buffer(np.ascontiguousarray(rgba).view(np.uint32).reshape(-1)), w, h)


@pytest.mark.parametrize("fmt", ["rgba8unorm", "bgra8unorm", "rgba8unorm-srgb"])
def test_compose_side_by_side_and_wipe(ctx, fmt):
    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (20, 30, 3), np.uint8)
    b = rng.integers(0, 256, (20, 30, 3), np.uint8)
    pa, pb = _picture(ctx, a), _picture(ctx, b)
    tol = 1 if fmt.endswith("srgb") else 0
    side = layout("side", 60, 24, aspect=1.5)
    img = _compose(ctx, fmt, side, [pa, pb], (60, 24))
    (ax, ay, aw, ah), (bx, by, bw, bh) = side.rects
    assert (aw, ah) == (30, 20)
    assert np.abs(img[ay:ay + ah, ax:ax + aw, :3].astype(int) - a).max() <= tol
    assert np.abs(img[by:by + bh, bx:bx + bw, :3].astype(int) - b).max() <= tol
    wipe = layout("wipe", 30, 20, aspect=1.5, wipe=0.5)
    img = _compose(ctx, fmt, wipe, [pa, pb], (30, 20))
    assert np.abs(img[:, :14, :3].astype(int) - a[:, :14]).max() <= tol
    assert np.abs(img[:, 16:, :3].astype(int) - b[:, 16:]).max() <= tol
    assert (img[:, 14:16, :3] >= 254).all()  # the wipe line
    # A missing picture leaves the letterbox colour.
    img = _compose(ctx, fmt, side, [pa, None], (60, 24))
    right = img[by:by + bh, bx:bx + bw, :3].astype(int)
    assert np.ptp(right.reshape(-1, 3), axis=0).max() == 0


def test_compose_scales_smoothly(ctx):
    grad = np.tile(np.linspace(0, 255, 8).astype(np.uint8)[None, :, None], (8, 1, 3))
    img = _compose(ctx, "rgba8unorm", layout("none", 32, 32), [_picture(ctx, grad)], (32, 32))
    row = img[16, :, 0].astype(int)
    assert (np.diff(row) >= 0).all() and row[0] <= 2 and row[-1] >= 253
