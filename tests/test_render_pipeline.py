"""The WGSL renderer against the numpy oracle (tests/render_oracle.py)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import render_oracle
from r360gpu.errors import InputError
from r360gpu.gpu import GpuContext
from r360gpu.io.camera import Camera
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.render import NO_COVERAGE_ALPHA, Render, Renderer, render, render_views
from r360gpu.render.conventions import NEAR_PLANE
from r360gpu.render.sort import VARIANT_ENV

RGB_TOL = 2e-3
DEPTH_REL_TOL = 1e-3


@pytest.fixture(autouse=True, params=["gpu-serial", "gpu-blocks", "cpu"])
def sort_backend(request, monkeypatch):
    """Every test here runs with the depth and tile sorts in WGSL, with either radix sort
    variant (render.sort.VARIANTS: serial for CPU adapters, blocks for GPUs), and on the
    host (the default on CPU adapters; GpuContext.kernel_backend)."""
    backend, _, variant = request.param.partition("-")
    monkeypatch.setenv("R360GPU_SORT", backend)
    monkeypatch.setenv(VARIANT_ENV, variant or "serial")
    return request.param


def camera(width=64, height=48, z=3.0, f=None, name="test", R=None, cx=None, cy=None):
    f = f or 0.9 * width
    return Camera(R=np.eye(3) if R is None else R, t=np.array([0.0, 0.0, z]), fx=f, fy=f * 1.05,
                  cx=width / 2 + 0.3 if cx is None else cx, cy=height / 2 - 0.2 if cy is None else cy,
                  width=width, height=height, name=name)


def look_at(eye, target, width, height, f):
    """A camera at ``eye`` looking at ``target`` (OpenCV axes, world y up -> image y down)."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    return Camera(R=R, t=-R @ eye, fx=f, fy=f, cx=width / 2, cy=height / 2, width=width, height=height)


def scene(means, scales, opacities, colors=None, quats=None, degree=0):
    means = np.asarray(means, np.float32).reshape(-1, 3)
    n = means.shape[0]
    scales = np.broadcast_to(np.asarray(scales, np.float32), (n, 3))
    opacities = np.broadcast_to(np.asarray(opacities, np.float32), (n,))
    quats = np.tile([1.0, 0, 0, 0], (n, 1)) if quats is None else quats
    sh = np.zeros((n, (degree + 1) ** 2, 3), np.float32)
    if colors is not None:
        sh[:, 0, :] = (np.broadcast_to(colors, (n, 3)) - 0.5) / 0.28209479177387814
    return Gaussians(means, scales, quats, opacities, sh)


def compare(got: Render, ref: dict):
    """RGB within RGB_TOL everywhere; depths within DEPTH_REL_TOL where both are covered."""
    assert got.rgb.shape == ref["rgb"].shape and got.rgb.dtype == np.float32
    np.testing.assert_allclose(got.rgb, ref["rgb"], rtol=0, atol=RGB_TOL)
    np.testing.assert_allclose(got.alpha, ref["alpha"], rtol=0, atol=RGB_TOL)
    # Coverage may only differ where alpha sits on the threshold.
    on_edge = np.abs(ref["alpha"] - NO_COVERAGE_ALPHA) < 1e-4
    cov_got, cov_ref = got.alpha >= NO_COVERAGE_ALPHA, ref["alpha"] >= NO_COVERAGE_ALPHA
    assert np.all((cov_got == cov_ref) | on_edge)
    both = cov_got & cov_ref
    for key in ("depth", "median_depth"):
        g, r = getattr(got, key), ref[key]
        np.testing.assert_allclose(g[both], r[both], rtol=DEPTH_REL_TOL, atol=0, err_msg=key)
        assert np.all(g[~cov_got] == 0), f"{key} must be 0 without coverage"


@pytest.mark.parametrize("size", [(64, 48), (67, 45)])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_random_scene_matches_oracle(ctx, size, degree):
    g = random_gaussians(1500 if degree == 3 else 600, sh_degree=degree, seed=10 * degree + size[0])
    cam = camera(*size)
    got = render(g, cam, ctx=ctx)
    ref = render_oracle.render(g, cam)
    assert got.alpha.max() > 0.9 and (got.depth > 0).mean() > 0.3  # the scene is really seen
    compare(got, ref)


def test_rotated_camera_and_background(ctx):
    g = random_gaussians(1200, sh_degree=3, seed=5)
    cam = look_at([2.5, 1.0, -2.0], [0.1, 0.0, 0.2], 67, 45, 50.0)
    bg = (0.2, 0.7, 1.0)
    got = render(g, cam, ctx=ctx, background=bg)
    compare(got, render_oracle.render(g, cam, background=bg))
    assert np.allclose(got.rgb[got.alpha == 0], bg)


def test_camera_inside_cloud(ctx):
    g = random_gaussians(2000, sh_degree=1, seed=7, extent=2.0)
    cam = look_at([0.1, 0.2, 0.0], [0.0, 0.0, 1.0], 64, 48, 40.0)
    got = render(g, cam, ctx=ctx)
    ref = render_oracle.render(g, cam)
    compare(got, ref)
    assert (got.alpha > 0.5).mean() > 0.5


def test_behind_camera_and_near_plane(ctx):
    cam = camera(64, 48, z=0.0)
    behind = scene([[0.0, 0.0, -1.0]], 0.5, 0.9, colors=[1, 0, 0])
    got = render(behind, cam, ctx=ctx)
    assert np.all(got.alpha == 0) and np.all(got.rgb == 0) and np.all(got.depth == 0)
    # Means just in front of / just behind the near plane, extending across it.
    straddle = scene([[0.0, 0.0, NEAR_PLANE + 0.01], [0.05, 0.0, NEAR_PLANE - 0.01], [0.0, 0.0, 2.0]],
                     [[0.3, 0.3, 0.3], [0.3, 0.3, 0.3], [0.5, 0.5, 0.5]], [0.6, 0.9, 0.8],
                     colors=[[0, 1, 0], [1, 0, 0], [0, 0, 1]])
    got = render(straddle, cam, ctx=ctx)
    compare(got, render_oracle.render(straddle, cam))
    assert got.rgb[..., 0].max() < 1e-6  # the one behind the near plane is culled
    assert got.rgb[..., 1].max() > 0.3


def test_huge_and_subpixel(ctx):
    cam = camera(67, 45, z=0.0)
    huge = scene([[0.0, 0.0, 5.0], [0.01, 0.0, 4.0], [-0.2, 0.1, 3.0]],
                 [[20.0, 20.0, 20.0], [1e-4, 1e-4, 1e-4], [2e-4, 1e-4, 3e-4]], [0.5, 0.95, 0.7],
                 colors=[[0.2, 0.4, 0.6], [1, 1, 1], [1, 0, 0]])
    renderer = Renderer(huge, ctx=ctx)
    got = renderer.render(cam)
    compare(got, render_oracle.render(huge, cam))
    assert np.all(got.alpha > 0.4)  # the huge one covers every tile
    assert renderer.stats.keys >= 15 + 2  # 5 x 3 tiles + one tile each for the sub-pixel ones
    renderer.release()


def test_empty_scene(ctx):
    # A duck-typed scene: Gaussians(...) itself rejects N = 0 (reshape of an empty SH array).
    empty = SimpleNamespace(means=np.zeros((0, 3), np.float32), scales=np.zeros((0, 3), np.float32),
                            quats=np.zeros((0, 4), np.float32), opacities=np.zeros(0, np.float32),
                            sh=np.zeros((0, 1, 3), np.float32))
    got = render(empty, camera(67, 45), ctx=ctx, background=(0.1, 0.2, 0.3))
    assert got.rgb.shape == (45, 67, 3)
    assert np.all(got.alpha == 0) and np.all(got.depth == 0) and np.all(got.median_depth == 0)
    assert np.allclose(got.rgb, [0.1, 0.2, 0.3])


@pytest.mark.parametrize("limit,n,scale", [(16384, 1000, (0.1, 0.5)), (16384, 1000, (2.0, 3.0))])
def test_keys_over_one_binding(ctx, limit, n, scale):
    """More keys than a (lowered) binding holds: the tiles are rendered in windows."""
    small = GpuContext(ctx.device, limit_binding_bytes=limit)
    rng = np.random.default_rng(n)
    g = random_gaussians(n, sh_degree=3, seed=n)
    g = Gaussians(g.means, np.exp(rng.uniform(*np.log(scale), (n, 3))), g.quats, g.opacities, g.sh)
    cam = camera(67, 45, z=4.0)
    renderer = Renderer(g, ctx=small)
    got = renderer.render(cam)
    assert renderer.stats.keys * 4 > small.max_binding_bytes
    assert renderer.stats.windows > 1
    compare(got, render_oracle.render(g, cam))
    # Same image as without windows.
    plain = render(g, cam, ctx=ctx)
    np.testing.assert_array_equal(plain.rgb, got.rgb)
    renderer.release()


def test_small_limits_everywhere(small_ctx):
    """4 KiB bindings and 7 workgroups per dimension (the shared fixture)."""
    g = random_gaussians(250, sh_degree=3, seed=3)
    cam = camera(32, 24, z=2.5)
    compare(render(g, cam, ctx=small_ctx), render_oracle.render(g, cam))


@pytest.mark.parametrize("where", ["gpu", "cpu"])
@pytest.mark.parametrize("size", [(67, 45), (64, 48), (1, 1)])
def test_numpy_readback_is_bit_exact(ctx, small_ctx, size, where, monkeypatch):
    """DeviceRender.to_numpy: colour interleaved on the device or on the host (the default on
    CPU adapters, and wherever the interleaved image exceeds a binding: small_ctx) gives every
    plane's bits, NaN payloads, infinities, -0 and subnormals included; the planes' padding is
    not read."""
    monkeypatch.setenv("R360GPU_RENDER_INTERLEAVE", where)
    from r360gpu.render import DeviceRender
    from r360gpu.render.rasterize import PLANES, plane_stride

    w, h = size
    stride = plane_stride(w, h)
    rng = np.random.default_rng(w * h)
    words = rng.integers(0, 2**32, (len(PLANES), stride), dtype=np.uint64).astype(np.uint32)
    special = np.array([0x7FC00001, 0xFFF00000, 0x7F800000, 0x80000000, 0x00000001, 0x7FBFFFFF], np.uint32)
    words[:, : min(special.size, w * h)] = special[: w * h]
    for c in (ctx, small_ctx):
        dev = DeviceRender(buffer=c.buffer(words.reshape(-1)), width=w, height=h, plane_stride=stride)
        got = dev.to_numpy(c)
        planes = {name: words[i, : w * h].reshape(h, w) for i, name in enumerate(PLANES)}
        np.testing.assert_array_equal(got.rgb.view(np.uint32), np.stack([planes[k] for k in "rgb"], axis=-1))
        for name in ("alpha", "depth", "median_depth"):
            np.testing.assert_array_equal(getattr(got, name).view(np.uint32), planes[name])
            assert getattr(got, name).shape == (h, w) and getattr(got, name).dtype == np.float32


def test_render_views_and_device_output(ctx):
    g = random_gaussians(500, sh_degree=2, seed=11)
    cams = [camera(64, 48, z=3.0), look_at([2.0, 0.5, -2.0], [0, 0, 0], 67, 45, 50.0), camera(64, 48, z=2.0)]
    views = list(render_views(g, cams, ctx=ctx))
    assert len(views) == 3
    for cam, got in zip(cams, views):
        single = render(g, cam, ctx=ctx)
        np.testing.assert_array_equal(got.rgb, single.rgb)
        np.testing.assert_array_equal(got.depth, single.depth)
    devs = list(render_views(g, cams, ctx=ctx, output="device"))
    for dev, got in zip(devs, views):
        back = dev.to_numpy(ctx)
        np.testing.assert_array_equal(back.rgb, got.rgb)
        np.testing.assert_array_equal(back.median_depth, got.median_depth)
        # Documented layout: plane 4 (depth) at 4 * 4 * plane_stride bytes, row-major.
        raw = ctx.read(dev.buffer, np.float32, dev.width * dev.height, 4 * 4 * dev.plane_stride)
        np.testing.assert_array_equal(raw.reshape(dev.height, dev.width), got.depth)


def test_work_counters(ctx):
    g = random_gaussians(700, sh_degree=1, seed=8)
    cam = camera(67, 45)
    renderer = Renderer(g, ctx=ctx, count_work=True, timed=True)
    renderer.render(cam)
    ref = render_oracle.render(g, cam)
    assert renderer.stats.blended == ref["blended"] > 0
    assert renderer.stats.evaluated >= renderer.stats.blended
    assert set(renderer.stats.times) == {"project", "sort", "rasterize"}
    renderer.release()


def test_deterministic(ctx):
    g = random_gaussians(800, sh_degree=3, seed=4)
    cam = camera(67, 45)
    a, b = render(g, cam, ctx=ctx), render(g, cam, ctx=ctx)
    for key in ("rgb", "alpha", "depth", "median_depth"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))


def test_bad_input(ctx):
    g = random_gaussians(10, seed=0)
    with pytest.raises(InputError):
        render(g, camera(), ctx=ctx, output="png")
    with pytest.raises(InputError):
        render(g, camera(), ctx=ctx, background=(1, 2))
    with pytest.raises(InputError):
        render(object(), camera(), ctx=ctx)
    with pytest.raises(InputError):
        render(g, object(), ctx=ctx)
    tiny = GpuContext(ctx.device, limit_binding_bytes=1024)
    with pytest.raises(InputError):
        render(g, camera(64, 48), ctx=tiny)  # not even one row of tiles fits the binding


def test_doctor_checks(ctx):
    from r360gpu.render import doctor_checks

    checks = doctor_checks(ctx, np.random.default_rng(0))
    assert len(checks) == 2
    for name, check in checks:
        ok, detail = check()
        assert ok, f"{name}: {detail}"


@pytest.mark.slow
def test_4096_square(ctx):
    """A 4096x4096 view (65,536 tiles, 16-bit tile keys) against the oracle on a region."""
    g = random_gaussians(3000, sh_degree=3, seed=21, extent=1.0)
    cam = Camera(R=np.eye(3), t=np.array([0.0, 0.0, 3.0]), fx=3000.0, fy=3000.0, cx=2048.0, cy=2048.0,
                 width=4096, height=4096)
    got = render(g, cam, ctx=ctx)
    assert got.alpha.shape == (4096, 4096)
    for x0, y0 in ((2000, 2040), (4096 - 67, 4096 - 45), (0, 0)):
        region = (slice(y0, y0 + 45), slice(x0, x0 + 67))
        ref = render_oracle.render(g, cam, window=(x0, y0, 67, 45))
        part = Render(rgb=got.rgb[region], depth=got.depth[region], median_depth=got.median_depth[region],
                      alpha=got.alpha[region])
        compare(part, ref)
    assert got.alpha[2000:2045, 2000:2067].mean() > 0.5


def test_sort_backends_give_the_same_image(ctx, monkeypatch):
    """Host and WGSL sorts (both radix variants): bit-equal images, with depth ties (equal z,
    so order by index decides), culled Gaussians and several key windows."""
    rng = np.random.default_rng(21)
    g = random_gaussians(1000, sh_degree=2, seed=21)
    means = g.means.copy()
    means[::3, 2] = means[0, 2]  # many Gaussians at exactly the same depth
    means[::11, 2] = -5.0  # behind the camera
    g = Gaussians(means, np.exp(rng.uniform(np.log(0.1), np.log(0.6), (1000, 3))), g.quats, g.opacities, g.sh)
    cam = camera(67, 45, z=4.0)
    small = GpuContext(ctx.device, limit_binding_bytes=16384)
    got = {}
    for backend in ("gpu-serial", "gpu-blocks", "cpu"):
        monkeypatch.setenv("R360GPU_SORT", backend.split("-")[0])
        monkeypatch.setenv(VARIANT_ENV, backend.split("-")[-1] if "-" in backend else "serial")
        renderer = Renderer(g, ctx=small)
        got[backend] = renderer.render(cam)
        assert renderer.stats.windows > 1
        renderer.release()
    for key in ("rgb", "alpha", "depth", "median_depth"):
        np.testing.assert_array_equal(getattr(got["cpu"], key), getattr(got["gpu-serial"], key))
        np.testing.assert_array_equal(getattr(got["cpu"], key), getattr(got["gpu-blocks"], key))
