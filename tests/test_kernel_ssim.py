"""SSIM / MSE kernels (GPU and CPU-adapter backends) against the float64 window definition."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.kernels.reference import ssim_reference
from r360gpu.kernels.ssim import MSE_RTOL, SSIM_TOL, ssim_backend, ssim_mse, ssim_mse_many
from r360gpu.metrics import fidelity as F

BACKENDS = ("gpu", "cpu")


def _check(posts, ref, ctx, backend):
    got = ssim_mse_many(posts, ref, ctx=ctx, backend=backend)
    scale = 255.0 if np.asarray(ref).dtype == np.uint8 else 1.0
    for (s, m), x in zip(got, posts):
        rs, rm = ssim_reference(np.asarray(x, np.float64) / scale, np.asarray(ref, np.float64) / scale)
        assert abs(s - rs) <= SSIM_TOL[backend], (s, rs)
        if scale == 255.0:
            assert m == pytest.approx(rm, rel=1e-12, abs=0)  # integer sum: exact up to the division
        else:
            assert m == pytest.approx(rm, rel=MSE_RTOL, abs=0)
    return got


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", [(11, 11, 3), (11, 11), (13, 17, 1), (40, 50, 3), (31, 67, 3), (12, 45)])
def test_random_images_match_reference(ctx, backend, shape):
    rng = np.random.default_rng(abs(hash(shape)) % 2**32)
    a = rng.integers(0, 256, shape, dtype=np.uint8)
    posts = [rng.integers(0, 256, shape, dtype=np.uint8), a, np.clip(a.astype(int) + 3, 0, 255).astype(np.uint8)]
    _check(posts, a, ctx, backend)
    _check([p.astype(np.float32) / 255 for p in posts], a.astype(np.float32) / 255, ctx, backend)


@pytest.mark.parametrize("backend", BACKENDS)
def test_adversarial_images(ctx, backend):
    h, w = 48, 70
    flat = np.full((h, w, 3), 250, np.uint8)
    dots = flat.copy()
    dots[::7, ::5] += 1  # tiny variance on a bright plateau: E[x^2] - E[x]^2 cancels
    bw = np.zeros((h, w, 3), np.uint8)
    bw[:, w // 2 :] = 255
    bw2 = bw.copy()
    bw2[::3, ::2] ^= 1
    black = np.zeros((h, w, 3), np.uint8)
    for posts, ref in (([dots, flat], flat), ([bw2, bw, black], bw), ([black], black)):
        got = _check(posts, ref, ctx, backend)
        _check([p.astype(np.float64) / 255 for p in posts], ref.astype(np.float64) / 255, ctx, backend)
    assert got[0] == (1.0, 0.0)  # identical images: SSIM 1, MSE 0 exactly


@pytest.mark.parametrize("backend", BACKENDS)
def test_bands_beyond_one_binding(ctx, backend):
    from r360gpu.gpu import GpuContext

    small = GpuContext(ctx.device, limit_binding_bytes=16384)  # 11 output rows per band
    rng = np.random.default_rng(5)
    a = rng.integers(0, 256, (200, 23, 3), dtype=np.uint8)  # the float32 image is 55 KB
    b = np.clip(a.astype(int) + rng.integers(-20, 21, a.shape), 0, 255).astype(np.uint8)
    _check([b, a], a, small, backend)
    _check([b.astype(np.float32) / 255], a.astype(np.float32) / 255, small, backend)
    with pytest.raises(InputError, match="do not fit one GPU storage binding"):
        ssim_mse_many([a], a, ctx=GpuContext(ctx.device, limit_binding_bytes=1024), backend="gpu")


def test_backends_agree_with_fidelity_on_a_larger_frame(ctx):
    import cv2

    rng = np.random.default_rng(9)
    base = cv2.GaussianBlur(rng.integers(0, 256, (180, 320, 3)).astype(np.uint8), (0, 0), 4)
    post = np.clip(base.astype(int) + rng.integers(-3, 4, base.shape), 0, 255).astype(np.uint8)
    s64 = F.ssim(post, base)
    for backend in BACKENDS:
        s, m = ssim_mse_many([post], base, ctx=ctx, backend=backend)[0]
        assert abs(s - s64) <= SSIM_TOL[backend]
        assert m == pytest.approx(F.mse(post, base), rel=1e-12)
    assert ssim_mse(post, base, ctx=ctx) == ssim_mse_many([post], base, ctx=ctx, backend=ssim_backend(ctx))[0]


def test_backend_choice(ctx, monkeypatch):
    monkeypatch.delenv("R360GPU_SSIM", raising=False)
    assert ssim_backend(ctx) == ("cpu" if ctx.adapter_info["adapter_type"] == "CPU" else "gpu")
    monkeypatch.setenv("R360GPU_SSIM", "gpu")
    assert ssim_backend(ctx) == "gpu"
    with pytest.raises(ValueError, match="unknown SSIM backend"):
        ssim_mse_many([np.zeros((12, 12), np.uint8)], np.zeros((12, 12), np.uint8), ctx=ctx, backend="tpu")


@pytest.mark.parametrize("backend", BACKENDS)
def test_bad_inputs(ctx, backend):
    good = np.zeros((12, 12, 3), np.float32)
    for bad, msg in (
        (np.full((12, 12, 3), np.nan, np.float32), "NaN or infinite"),
        (np.where(np.eye(12, dtype=bool)[:, :, None], np.inf, 0).astype(np.float32), "NaN or infinite"),
        (np.full((12, 12, 3), 1.5, np.float32), "outside"),
        (np.zeros((12, 12, 3), np.int32), "uint8 or float"),
        (np.zeros((12, 13, 3), np.float32), "I_ref is"),
    ):
        with pytest.raises(InputError, match=msg):
            ssim_mse_many([bad], good, ctx=ctx, backend=backend)
    with pytest.raises(InputError, match="at least 11x11"):
        ssim_mse_many([np.zeros((1, 1), np.uint8)], np.zeros((1, 1), np.uint8), ctx=ctx, backend=backend)
    with pytest.raises(InputError, match="uint8 or both to float"):
        ssim_mse_many([np.zeros((12, 12), np.uint8)], np.zeros((12, 12), np.float32), ctx=ctx, backend=backend)
    assert ssim_mse_many([], good, ctx=ctx, backend=backend) == []


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
def test_cpu_backend_is_the_same_for_any_thread_count(monkeypatch, dtype):
    from r360gpu.kernels import ssim as S

    rng = np.random.default_rng(11)
    y = rng.integers(0, 256, (300, 97, 3)).astype(np.uint8)  # 290 output rows: 5 strips, the last short
    xs = [np.clip(y.astype(np.int16) + rng.integers(-30, 31, y.shape), 0, 255).astype(np.uint8) for _ in range(3)]
    if dtype == np.float32:
        y, xs = y.astype(np.float32) / 255, [x.astype(np.float32) / 255 for x in xs]
    got = {}
    for n in (1, 2, 3):
        monkeypatch.setattr(S, "CPU_THREADS", n)
        got[n] = S._ssim_mse_cpu(xs, y)
    assert got[1] == got[2] == got[3]
    # the MSE is summed strip by strip (each strip its own image rows, the last to the bottom row)
    scale = 255.0 if dtype == np.uint8 else 1.0
    for (_, m), x in zip(got[1], xs):
        d = np.asarray(x, np.float64) / scale - np.asarray(y, np.float64) / scale
        assert m == pytest.approx(float(np.mean(d * d)), rel=1e-12 if dtype == np.uint8 else MSE_RTOL, abs=0)
