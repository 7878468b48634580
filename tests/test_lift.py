"""Target lifting (r360gpu.lift): the WGSL pass against the numpy reference, targets from
indices, PLY labels and boxes, and target masks rendered at any pose."""
from __future__ import annotations

import numpy as np
import pytest

import lift_oracle
import render_oracle
from r360gpu.errors import InputError
from r360gpu.gpu import GpuContext
from r360gpu.io.camera import Camera
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.lift.device import MaskLifter
from r360gpu.lift.masks import MASK_SHARE, TargetMaskRenderer, label_scene, target_masks
from r360gpu.lift.target import Box, decide, lift_target, load_indices, target_from_box, target_from_indices
from r360gpu.render import render


def camera(width=67, height=45, z=3.0, name="v", angle=0.0):
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
    return Camera(R=R, t=np.array([0.0, 0.0, z]), fx=0.9 * width, fy=0.95 * width, cx=width / 2 + 0.3,
                  cy=height / 2 - 0.2, width=width, height=height, name=name)


def tolerance(ref_total):
    # Per thread and Gaussian the kernel rounds to 1/SCALE; its weights are float32.
    return 1e-4 + 2e-5 * ref_total


def check(ctx, g, cams, masks):
    lifter = MaskLifter(g, ctx=ctx)
    for c, m in zip(cams, masks):
        lifter.add_view(c, m)
    w_in, w_out = lifter.weights()
    lifter.release()
    r_in, r_out = lift_oracle.lift_weights(g, cams, masks)
    np.testing.assert_allclose(w_in, r_in, rtol=0, atol=tolerance(r_in + r_out).max())
    np.testing.assert_allclose(w_out, r_out, rtol=0, atol=tolerance(r_in + r_out).max())
    return w_in, w_out


@pytest.mark.parametrize("size", [(64, 48), (67, 45), (17, 1)])
def test_random_scene_matches_reference(ctx, size):
    g = random_gaussians(500, sh_degree=1, seed=size[0])
    rng = np.random.default_rng(size[1])
    cams = [camera(*size, angle=a, name=f"v{i}") for i, a in enumerate((0.0, 0.4))]
    masks = [rng.random(size[::-1]) < 0.4, rng.random(size[::-1]).astype(np.float32)]  # hard and soft
    w_in, w_out = check(ctx, g, cams, masks)
    assert w_in.sum() > 1 and w_out.sum() > 1  # the views really see the scene


def test_weights_add_up_to_the_rendered_alpha(ctx):
    """Per view, the Gaussians' weights sum to the rendered coverage sum(1 - T) (one compositing)."""
    g = random_gaussians(800, sh_degree=0, seed=4)
    cam = camera(64, 48)
    lifter = MaskLifter(g, ctx=ctx)
    lifter.add_view(cam, np.ones((48, 64), bool))
    w_in, w_out = lifter.weights()
    lifter.release()
    assert np.all(w_out == 0)
    alpha = render(g, cam, ctx=ctx).alpha
    assert abs(w_in.sum() - alpha.sum()) < 1e-3 * alpha.sum()


def test_empty_mask_one_pixel_and_no_gaussian_in_view(ctx):
    g = random_gaussians(300, sh_degree=0, seed=6)
    w_in, w_out = check(ctx, g, [camera(64, 48)], [np.zeros((48, 64), bool)])
    assert np.all(w_in == 0) and w_out.sum() > 0
    check(ctx, g, [camera(1, 1)], [np.ones((1, 1), bool)])
    away = Camera(R=np.eye(3), t=np.array([0.0, 0.0, -5.0]), fx=50, fy=50, cx=32, cy=24, width=64, height=48)
    w_in, w_out = check(ctx, g, [away], [np.ones((48, 64), bool)])
    assert np.all(w_in == 0) and np.all(w_out == 0)


def test_keys_over_one_binding_give_the_same_weights(ctx):
    """Tiles split into key windows (a lowered binding limit): weights as with one window."""
    g = random_gaussians(1000, sh_degree=0, seed=8)
    g = Gaussians(g.means, g.scales * 20, g.quats, g.opacities, g.sh)
    cam, mask = camera(67, 45, z=4.0), np.random.default_rng(1).random((45, 67)) < 0.5
    small = GpuContext(ctx.device, limit_binding_bytes=16384)
    lifter = MaskLifter(g, ctx=small)
    lifter.add_view(cam, mask)
    assert lifter.renderer.stats.windows > 1
    got = lifter.weights()
    lifter.release()
    whole = MaskLifter(g, ctx=ctx)
    whole.add_view(cam, mask)
    want = whole.weights()
    whole.release()
    np.testing.assert_allclose(got[0], want[0], atol=1e-5)
    np.testing.assert_allclose(got[1], want[1], atol=1e-5)


def test_device_mask_buffer(ctx):
    g = random_gaussians(300, sh_degree=0, seed=2)
    cam = camera(33, 21)
    mask = (np.random.default_rng(3).random((21, 33)) < 0.5).astype(np.float32)
    lifter = MaskLifter(g, ctx=ctx)
    lifter.add_view(cam, ctx.buffer(mask))
    on_device = lifter.weights()
    lifter.reset()
    lifter.add_view(cam, mask)
    assert np.array_equal(on_device[0], lifter.weights()[0])
    with pytest.raises(InputError, match="needs"):
        lifter.add_view(cam, ctx.buffer(np.zeros(10, np.float32)))
    lifter.release()


def test_bad_masks(ctx):
    g = random_gaussians(50, sh_degree=0, seed=1)
    cam = camera(16, 8)
    bad_nan = np.zeros((8, 16), np.float32)
    bad_nan[2, 3] = np.nan
    bad_inf = np.zeros((8, 16), np.float32)
    bad_inf[0, 0] = np.inf
    with pytest.raises(InputError, match="NaN"):
        lift_target(g, [cam], [bad_nan], ctx=ctx)
    with pytest.raises(InputError, match="NaN"):
        lift_target(g, [cam], [bad_inf], ctx=ctx)
    with pytest.raises(InputError, match="16x8"):
        lift_target(g, [cam], [np.zeros((9, 16), bool)], ctx=ctx)
    with pytest.raises(InputError, match="2 cameras but 1"):
        lift_target(g, [cam, cam], [np.zeros((8, 16), bool)], ctx=ctx)
    with pytest.raises(InputError, match="no views"):
        lift_target(g, [], [], ctx=ctx)


def test_decide_rule():
    w_in = np.array([0.0, 1.0, 0.5, 0.02, 3.0, 0.0])
    w_out = np.array([0.0, 1.0, 0.6, 0.0, 0.1, 5.0])
    assert decide(w_in, w_out).tolist() == [False, True, False, False, True, False]
    assert decide(w_in, w_out, min_weight=0.01).tolist() == [False, True, False, True, True, False]


def _two_blobs():
    """A target blob in front of a wall of background Gaussians."""
    rng = np.random.default_rng(0)
    wall = np.c_[rng.uniform(-1.5, 1.5, (3000, 2)), np.full(3000, 1.0)]
    blob = rng.normal(0, 0.15, (600, 3)) + [0.0, 0.0, -0.3]
    means = np.r_[wall, blob].astype(np.float32)
    n = len(means)
    scales = np.r_[np.full((3000, 3), 0.04), np.full((600, 3), 0.05)].astype(np.float32)
    sh = np.zeros((n, 1, 3), np.float32)
    g = Gaussians(means, scales, np.tile([1.0, 0, 0, 0], (n, 1)), np.full(n, 0.9, np.float32), sh)
    truth = np.r_[np.zeros(3000, bool), np.ones(600, bool)]
    return g, truth


def test_lift_from_two_views_finds_the_object(ctx):
    g, truth = _two_blobs()
    cams = [camera(64, 48, z=3.0, angle=a, name=f"v{i}") for i, a in enumerate((-0.4, 0.45, 0.05))]
    oracle_masks = [render_oracle.render(label_scene(g, truth), c)["rgb"][..., 0] >= MASK_SHARE for c in cams]
    lifted = lift_target(g, cams[:2], oracle_masks[:2], ctx=ctx)
    # Precision and recall weighted by what the given views see of each Gaussian (its total
    # compositing weight): background seen only through the object's fringe counts for little.
    w = lifted.w_in + lifted.w_out
    tp = (w * (lifted.target & truth)).sum()
    assert tp / (w * lifted.target).sum() >= 0.98 and tp / (w * truth).sum() >= 0.98
    # The held-out third view: the lifted target's mask matches the true one.
    got = next(target_masks(g, lifted.target, [cams[2]], ctx=ctx))
    iou = (got & oracle_masks[2]).sum() / (got | oracle_masks[2]).sum()
    assert iou >= 0.95


def test_target_masks_match_the_reference_render(ctx):
    g = random_gaussians(600, sh_degree=2, seed=9)
    target = np.random.default_rng(2).random(g.n) < 0.3
    cams = [camera(67, 45), camera(31, 17, angle=0.5)]
    for cam, got in zip(cams, target_masks(g, target, cams, ctx=ctx)):
        share = render_oracle.render(label_scene(g, target), cam)["rgb"][..., 0]
        edge = np.abs(share - MASK_SHARE) < 2e-3
        assert got.shape == (cam.height, cam.width) and got.dtype == bool
        assert np.all((got == (share >= MASK_SHARE)) | edge)
    none = next(target_masks(g, np.zeros(g.n, bool), cams[:1], ctx=ctx))
    assert not none.any()
    everything = TargetMaskRenderer(g, np.ones(g.n, bool), ctx=ctx)
    np.testing.assert_allclose(everything.share(cams[0]), render(g, cams[0], ctx=ctx).alpha, atol=1e-5)
    dev = everything.device(cams[0])
    assert dev.width == 67
    everything.release()
    with pytest.raises(InputError, match="entries"):
        label_scene(g, np.zeros(3, bool))
    with pytest.raises(InputError, match="output"):
        next(target_masks(g, target, cams, output="png"))


def test_target_from_indices_npy_ply_and_box(tmp_path):
    from r360gpu.io.ply import write_ply

    t = target_from_indices(5, [4, 1, 1])
    assert t.target.tolist() == [False, True, False, False, True] and t.indices.tolist() == [1, 4]
    np.save(tmp_path / "idx.npy", np.array([0, 2]))
    assert load_indices(tmp_path / "idx.npy", 3).indices.tolist() == [0, 2]
    np.save(tmp_path / "bool.npy", np.array([True, False, True]))
    assert load_indices(tmp_path / "bool.npy", 3).indices.tolist() == [0, 2]
    vert = np.zeros(4, dtype=[("x", "<f4"), ("label", "<i4")])
    vert["label"] = [0, 3, 0, 1]
    write_ply(tmp_path / "labels.ply", [("vertex", vert)])
    assert load_indices(tmp_path / "labels.ply", 4).indices.tolist() == [1, 3]
    for bad, match in ((lambda: target_from_indices(3, [5]), "outside"), (lambda: target_from_indices(3, []), "no G"),
                       (lambda: target_from_indices(3, [0.5]), "whole"),
                       (lambda: target_from_indices(3, np.ones(2, bool)), "one entry"),
                       (lambda: load_indices(tmp_path / "labels.ply", 5), "4 vertices"),
                       (lambda: load_indices(tmp_path / "missing.npy", 3), "does not exist"),
                       (lambda: load_indices(tmp_path / "labels.ply", 4, prop="seg"), "no target property")):
        with pytest.raises(InputError, match=match):
            bad()
    (tmp_path / "idx.txt").write_text("1 2")
    with pytest.raises(InputError, match=".npy or .ply"):
        load_indices(tmp_path / "idx.txt", 3)

    pts = np.array([[0, 0, 0], [0.9, 0, 0], [1.1, 0, 0], [0, 0.5, 0.5]], float)
    aabb = Box.from_table({"min": [-1, -1, -1], "max": [1, 1, 1]})
    assert aabb.contains(pts).tolist() == [True, True, False, True]
    # An oriented box rotated 45 degrees about z: (0.9, 0, 0) is outside its 1.4 x 0.2 x 1 extent.
    q = [np.cos(np.pi / 8), 0, 0, np.sin(np.pi / 8)]
    obb = Box.from_table({"centre": [0, 0, 0], "size": [1.4, 0.2, 1], "rotation": q})
    diag = np.array([[0.45, 0.45, 0], [0.9, 0, 0], [-0.45, -0.45, 0]])
    assert obb.contains(diag).tolist() == [True, False, True]
    assert target_from_box(pts, aabb).indices.tolist() == [0, 1, 3]
    for table, match in (({"min": [0, 0, 0], "max": [-1, 0, 0]}, "max must be"), ({"min": [0, 0]}, "needs min"),
                         ({"centre": [0, 0, 0], "size": [1, 1, np.nan]}, "finite"),
                         ({"centre": [0, 0, 0], "size": [1, 1, 1], "rotation": [[2, 0, 0]] * 3}, "rotation"),
                         ("box", "must be a table")):
        with pytest.raises(InputError, match=match):
            Box.from_table(table)
    with pytest.raises(InputError, match="no Gaussian centre"):
        target_from_box(pts + 10, aabb)
