"""SSIM and MSE of image pairs, batched over the methods of a view: a GPU
kernel (host side of ``shaders/ssim.wgsl``) and, for CPU adapters, a
float32 OpenCV path.

Definition (written once in :mod:`r360gpu.metrics.fidelity`): 11 x 11
Gaussian window (sigma 1.5, normalised), C1 = (0.01 L)^2, C2 = (0.03 L)^2,
population statistics, map over the valid region only, mean over positions
and channels.  uint8 images are read as bytes (L = 255, squared differences
summed exactly in integers); float images as float32 in [0, 1] (L = 1).

Backends (:func:`ssim_backend`):

``gpu``
    the WGSL kernel.  float32, but it never forms a variance as
    E[x^2] - E[x]^2 (see the shader header); mean SSIM within 1e-6 (tested; about 1e-7 seen) of the
    float64 window definition in the tests.
``cpu``
    on CPU adapters (lavapipe) a compute shader is a slower way to run the
    same CPU: its per-invocation storage loads make this 11 x 11 stencil
    several times slower than OpenCV's vectorised separable filter (10x at
    1080p, 3 methods, in bench/bench_measure.py's last rows).  This path
    filters float32 images with cv2.sepFilter2D after subtracting each
    channel's mean of I_ref (so E[x^2] - E[x]^2 cancels on values near 0,
    not near 1), by strips of rows, and
    filters I_ref once for all methods.

Both stay within ``SSIM_TOL[backend]`` of the float64 window definition
(:func:`r360gpu.kernels.reference.ssim_reference`) on random, smooth,
flat-bright and black/white images; MSE is exact for uint8 and within
``MSE_RTOL`` (relative) for floats.  Checked in tests/test_kernel_ssim.py.

:func:`ssim_mse_many` measures several images (the methods of one view)
against one reference in one submission; the reference is uploaded once.
Images larger than a storage binding are processed in bands of rows
(10 rows of overlap).
"""
from __future__ import annotations

import math
import os
import threading
from collections.abc import Sequence

import cv2
import numpy as np

from ..errors import InputError
from ..gpu.context import GpuContext, get_context
from ..gpu.shaders import shader_constants

SHADER = "ssim"
#: The WGSL names of the resources the calls here bind, by position (checked at pipeline creation).
BINDINGS = ("P", "img_x", "img_y", "hs", "partial")
WIN = 11
SIGMA = 1.5
K1, K2 = 0.01, 0.03
_SIZES = shader_constants(SHADER)  # sizes ssim.wgsl states: RB output rows per ssim_v invocation,
RB, SQ, WG = _SIZES["RB"], _SIZES["SQ"], _SIZES["WG"]  # SQ words per sqdiff invocation, WG invocations
#: |mean SSIM - float64 definition|, per backend.  cpu: a bound, not a
#: typical value: float32 rounding of E[x^2] and E[x]^2 (values within 0.5 of
#: the shift) is about 4 * 2^-24 * 0.25 = 6e-8 against C2 = 9e-4, i.e. <= 1e-4
#: relative per position; measured <= 2e-5 on black/white images.
SSIM_TOL = {"gpu": 1e-6, "cpu": 1e-4}
MSE_RTOL = 1e-6  # relative error of the float MSE (uint8: exact)


def ssim_backend(ctx: GpuContext) -> str:
    """"gpu" or "cpu" for this adapter (see the module docstring and
    :meth:`GpuContext.kernel_backend`); ``R360GPU_SSIM`` overrides."""
    return ctx.kernel_backend("ssim")


def gaussian_taps() -> np.ndarray:
    """float64 (11,) Gaussian window, sum 1 (as metrics.fidelity.gaussian_window)."""
    x = np.arange(WIN, dtype=np.float64) - (WIN - 1) / 2.0
    g = np.exp(-(x * x) / (2.0 * SIGMA * SIGMA))
    return g / g.sum()


def image_hwc(img, what: str) -> np.ndarray:
    """``img`` as (H, W, C) with C 1 or 3 (a gray (H, W) image gets C = 1); InputError otherwise."""
    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 3) or a.shape[0] < 1 or a.shape[1] < 1:
        raise InputError(f"{what} must be (H, W, 3) RGB or (H, W) gray, got shape {np.shape(img)}")
    return a


def check_image(img, what: str) -> np.ndarray:
    """(H, W, C) uint8 or float32 view of an image; floats must lie in [0, 1].

    One min and one max (NaN propagates through both, and +-Inf is out of
    range) replace a separate finiteness pass.
    """
    a = image_hwc(img, what)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    if not np.issubdtype(a.dtype, np.floating):
        raise InputError(f"{what} must be uint8 or float in [0, 1], got dtype {a.dtype}")
    lo, hi = float(np.min(a)), float(np.max(a))
    if not (lo >= 0.0 and hi <= 1.0):
        if math.isnan(lo) or math.isnan(hi) or not np.isfinite(a).all():
            raise InputError(f"{what} contains NaN or infinite values")
        raise InputError(f"{what} has values in [{lo:.6g}, {hi:.6g}], outside [0, 1]")
    return np.ascontiguousarray(a, np.float32)


def _band_rows(ctx: GpuContext, w: int, c: int, itemsize: int) -> int:
    """Output rows per band so the image rows, the 5 planes and the partial sums fit one binding."""
    per = ctx.max_binding_bytes
    vw = w - (WIN - 1)
    by_img = per // (w * c * itemsize) - (WIN - 1)
    by_hs = per // (5 * 4 * c * vw) - (WIN - 1)
    by_part = (per // (4 * c * vw)) * RB
    rows = min(by_img, by_hs, by_part)
    if rows < 1:
        raise InputError(f"image rows of {w} pixels x {c} channels do not fit one GPU storage binding")
    return rows


def _words(a: np.ndarray) -> np.ndarray:
    """The bytes of a contiguous array as u32 words (zero-padded)."""
    raw = a.reshape(-1).view(np.uint8)
    if raw.size % 4:
        raw = np.concatenate([raw, np.zeros(-raw.size % 4, np.uint8)])
    return raw.view(np.uint32)


def ssim_mse_many(posts: Sequence, ref, *, ctx: GpuContext | None = None,
                  what: Sequence[str] | None = None, backend: str | None = None) -> list[tuple[float, float]]:
    """[(mean SSIM, MSE)] of every image of ``posts`` against ``ref``.

    Images: (H, W, 3) or (H, W), uint8 or float in [0, 1], all of one size
    and of one kind (all uint8 or all float).  MSE is on the [0, 1] scale.
    Images smaller than 11 pixels in either dimension are an input error.
    what: names of the posts for error messages; backend: "gpu" / "cpu"
    (default: :func:`ssim_backend`).
    """
    ctx = ctx or get_context()
    backend = backend or ssim_backend(ctx)
    if backend not in ("gpu", "cpu"):
        raise ValueError(f"unknown SSIM backend {backend!r}")
    names = list(what) if what is not None else [f"image {i}" for i in range(len(posts))]
    y = check_image(ref, "I_ref")
    xs = [check_image(p, n) for p, n in zip(posts, names)]
    for x, n in zip(xs, names):
        if x.shape != y.shape:
            raise InputError(f"{n} is {x.shape} but I_ref is {y.shape} (H, W, C)")
        if x.dtype != y.dtype:
            raise InputError(f"{n} is {x.dtype} but I_ref is {y.dtype}: convert both to uint8 or both to float")
    h, w, c = y.shape
    if h < WIN or w < WIN:
        raise InputError(f"SSIM needs images of at least {WIN}x{WIN} pixels, got {h}x{w}")
    if not xs:
        return []
    if backend == "cpu":
        return _ssim_mse_cpu(xs, y)
    u8 = y.dtype == np.uint8
    itemsize = 1 if u8 else 4
    scale = 255.0 if u8 else 1.0
    g = gaussian_taps().astype(np.float32)
    c1, c2 = (K1 * scale) ** 2, (K2 * scale) ** 2
    vh, vw = h - (WIN - 1), w - (WIN - 1)
    band = _band_rows(ctx, w, c, itemsize)
    p_h, p_v, p_sq = (ctx.pipeline(SHADER, e, {"IS_U8": int(u8)}, bindings=BINDINGS)
                      for e in ("ssim_h", "ssim_v", "sqdiff"))
    sums = np.zeros(len(xs), np.float64)
    sq = np.zeros(len(xs), np.float64)
    for o0 in range(0, vh, band):
        o1 = min(vh, o0 + band)
        rows_in = o1 - o0 + WIN - 1
        # Squared differences: every image row exactly once over the bands.
        s0 = 0 if o0 == 0 else o0 + WIN - 1
        s1 = o1 + WIN - 1
        yb = ctx.buffer(_words(y[o0 : o0 + rows_in]), label="ssim_ref")
        n_blocks = -(-(o1 - o0) // RB)
        n_h = c * rows_in * vw
        n_v = c * n_blocks * vw
        hs = ctx.buffer(5 * n_h * 4, label="ssim_hs")
        # The first band's buffers hold exactly rows s0:s1; later bands copy them.
        n_words = math.ceil((s1 - s0) * w * c * itemsize / 4)
        enc = ctx.encoder()
        outs = []
        for k, x in enumerate(xs):
            xb = ctx.buffer(_words(x[o0 : o0 + rows_in]), label="ssim_post")
            part = ctx.buffer(n_v * 4, label="ssim_partial")
            params = ctx.uniform(w, c, rows_in, o1 - o0, vw, n_blocks, int(u8), n_words, np.float32(c1),
                                 np.float32(c2), 0, 0, *(np.float32(t) for t in g[:6]), 0, 0)
            ctx.dispatch(enc, p_h, [params, xb, yb, hs], ctx.grid(math.ceil(n_h / WG)))
            ctx.dispatch(enc, p_v, [params, None, None, hs, part], ctx.grid(math.ceil(n_v / WG)))
            if s0 == o0:
                xa, ya = xb, yb
            else:
                xa = ctx.buffer(_words(x[s0:s1]), label="ssim_sq_x")
                ya = ctx.buffer(_words(y[s0:s1]), label="ssim_sq_y")
            n_sq = math.ceil(n_words / SQ)
            sq_part = ctx.buffer(n_sq * 4, label="ssim_sq")
            ctx.dispatch(enc, p_sq, [params, xa, ya, None, sq_part], ctx.grid(math.ceil(n_sq / WG)))
            outs.append((part, n_v, sq_part, n_sq))
        ctx.submit(enc)
        for k, (part, nv, sq_part, nsq) in enumerate(outs):
            sums[k] += ctx.read(part, np.float32, nv).astype(np.float64).sum()
            if u8:
                sq[k] += float(ctx.read(sq_part, np.uint32, nsq).astype(np.int64).sum())
            else:
                sq[k] += ctx.read(sq_part, np.float32, nsq).astype(np.float64).sum()
    n_valid = vh * vw * c
    n_all = h * w * c
    return [(float(s / n_valid), float(q / (scale * scale) / n_all)) for s, q in zip(sums, sq)]


STRIP = 64  # output rows per strip of the cpu backend (arrays stay cache-sized)


def _filter(img: np.ndarray, g: np.ndarray, out: np.ndarray) -> np.ndarray:
    """float32 separable Gaussian of (rows, W, C) into ``out``, valid rows and columns only."""
    r = WIN // 2
    full = cv2.sepFilter2D(img, cv2.CV_32F, g, g, borderType=cv2.BORDER_REFLECT)
    if full.ndim == 2:
        full = full[:, :, None]
    out[...] = full[r:-r, r:-r]
    return out


#: Threads the cpu backend filters strips in (the machine's cores, at most 4).
CPU_THREADS = max(1, min(4, os.cpu_count() or 1))


def _strip_buffers(rows: int, w: int, c: int) -> tuple:
    f32 = lambda shape: np.empty(shape, np.float32)  # noqa: E731
    vw = w - (WIN - 1)
    big = tuple(f32((rows + WIN - 1, w, c)) for _ in range(3))
    # the last: squared errors in float64, over a strip's rows (the last strip's reach the bottom)
    return big + tuple(f32((rows, vw, c)) for _ in range(8)) + (np.empty((rows + WIN - 1, w, c), np.float64),)


def _squared_error(x: np.ndarray, y: np.ndarray, d32: np.ndarray, d64: np.ndarray) -> float:
    """Sum of squared differences of two row blocks, in the buffers d32 / d64 (at least as many
    rows): exact for uint8 (|x - y| squared in uint16, summed in uint64), else float32
    differences squared and summed (pairwise) in float64.  The buffers are the thread's own and
    reused strip after strip, so no image-sized temporary is allocated and faulted in per strip."""
    n = x.shape[0]
    if y.dtype == np.uint8:
        d = d32.view(np.uint16).reshape(-1)[: x.size]
        np.copyto(d, cv2.absdiff(x, y).reshape(-1))
        d *= d  # 255^2 fits uint16
        return float(d.sum(dtype=np.uint64))
    d, d2 = d32[:n], d64[:n]
    np.subtract(x, y, out=d)
    d2[...] = d
    np.square(d2, out=d2)
    # numpy's pairwise sum, not BLAS dot: BLAS splits the sum by its thread count, which
    # differs between processes (Ray workers run single-threaded), and so would the last bits
    return float(d2.sum())


def _rows(a: np.ndarray) -> np.ndarray:
    """A contiguous (rows, W, C) block as (rows, W * C): a per-channel constant tiled along the
    row then broadcasts with a W * C long inner loop (against (C,), numpy's inner loop is C long)."""
    return a.reshape(a.shape[0], -1)


def _strip_sums(xs, y, shift, strip, bufs, g, c1, c2) -> tuple[np.ndarray, np.ndarray]:
    """Summed SSIM map of every method over output rows ``strip`` (o0, o1, e0, e1), and
    summed squared error over image rows [e0, e1): float64 (len(xs),) each.

    shift: I_ref's channel means tiled along a row, (W * C,) float32."""
    o0, o1, e0, e1 = strip
    ys, xc, t, my, vy_c2, my2, my_sq_c1, mx, sxx, sxy, tmp, sq64 = bufs
    n_in, n_out = o1 - o0 + WIN - 1, o1 - o0
    yc, xcs, ts = ys[:n_in], xc[:n_in], t[:n_in]
    m_y, v_y, m_y2, m_yc = my[:n_out], vy_c2[:n_out], my2[:n_out], my_sq_c1[:n_out]
    m_x, s_xx, s_xy, q = mx[:n_out], sxx[:n_out], sxy[:n_out], tmp[:n_out]
    shift_v = shift[: m_y.shape[1] * m_y.shape[2]]  # the valid columns' share (the tiling is periodic)
    sums = np.zeros(len(xs), np.float64)
    sq = np.array([_squared_error(x[e0:e1], y[e0:e1], t, sq64) for x in xs], np.float64)
    # I_ref's share, once per strip for all methods (values shifted by its channel means).
    np.subtract(_rows(y[o0 : o0 + n_in]), shift, out=_rows(yc), dtype=np.float32)
    _filter(yc, g, m_y)
    np.multiply(yc, yc, out=ts)
    _filter(ts, g, v_y)
    np.multiply(m_y, m_y, out=q)
    v_y -= q
    v_y += c2  # syy + C2
    np.add(_rows(m_y), shift_v, out=_rows(m_y2))
    np.multiply(m_y2, m_y2, out=m_yc)
    m_yc += c1  # my^2 + C1
    m_y2 *= np.float32(2.0)  # 2 my
    for k, x in enumerate(xs):
        np.subtract(_rows(x[o0 : o0 + n_in]), shift, out=_rows(xcs), dtype=np.float32)
        _filter(xcs, g, m_x)
        np.multiply(xcs, xcs, out=ts)
        _filter(ts, g, s_xx)
        np.multiply(xcs, yc, out=ts)
        _filter(ts, g, s_xy)
        np.multiply(m_x, m_x, out=q)
        s_xx -= q
        s_xx += v_y  # sxx + syy + C2
        np.multiply(m_x, m_y, out=q)
        s_xy -= q
        s_xy *= np.float32(2.0)
        s_xy += c2  # 2 sxy + C2
        np.add(_rows(m_x), shift_v, out=_rows(m_x))
        np.multiply(m_x, m_x, out=q)
        q += m_yc
        q *= s_xx  # (mx^2 + my^2 + C1)(sxx + syy + C2)
        m_x *= m_y2
        m_x += c1
        m_x *= s_xy  # (2 mx my + C1)(2 sxy + C2)
        m_x /= q
        sums[k] = m_x.sum(dtype=np.float64)
    return sums, sq


def _ssim_mse_cpu(xs: list[np.ndarray], y: np.ndarray) -> list[tuple[float, float]]:
    """SSIM and MSE by strips of rows (each strip's I_ref statistics shared by
    every method; each strip's squared errors summed over its own image rows,
    so no whole-image temporary is made).

    Strips are filtered in up to ``CPU_THREADS`` threads (OpenCV and numpy
    release the GIL on arrays this size); each strip's sums are kept and
    added in strip order, so the result does not depend on the thread count.
    """
    from concurrent.futures import ThreadPoolExecutor

    u8 = y.dtype == np.uint8
    scale = np.float32(255.0 if u8 else 1.0)
    h, w, c = y.shape
    vh, vw = h - (WIN - 1), w - (WIN - 1)
    # cv2.mean (float64 sums, <= 4 channels) in one contiguous pass; numpy's axis-0 mean is a strided one
    mean = cv2.mean(y)[:c] if c <= 4 else y.reshape(-1, c).mean(axis=0, dtype=np.float64)
    shift = np.tile(np.asarray(mean, np.float64).astype(np.float32), w)
    rows = min(STRIP, vh)
    # output rows [o0, o1); squared errors over image rows [o0, o1), the last strip to the bottom
    strips = [(o0, min(vh, o0 + rows), o0, min(vh, o0 + rows) if o0 + rows < vh else h) for o0 in range(0, vh, rows)]
    consts = (gaussian_taps().astype(np.float32), np.float32((K1 * scale) ** 2), np.float32((K2 * scale) ** 2))
    threads = max(1, min(CPU_THREADS, len(strips)))
    local = threading.local()

    def run(strip):
        if not hasattr(local, "bufs"):
            local.bufs = _strip_buffers(rows, w, c)
        return _strip_sums(xs, y, shift, strip, local.bufs, *consts)

    if threads == 1:
        per_strip = [run(st) for st in strips]
    else:
        with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="r360-ssim") as pool:
            per_strip = list(pool.map(run, strips))
    sums = np.zeros(len(xs), np.float64)
    sq = np.zeros(len(xs), np.float64)
    for part, part_sq in per_strip:  # in strip order, whatever thread computed it
        sums += part
        sq += part_sq
    return [(float(sums[k] / (vh * vw * c)), float(sq[k]) / float(scale * scale) / (h * w * c))
            for k in range(len(xs))]


def ssim_mse(post, ref, *, ctx: GpuContext | None = None) -> tuple[float, float]:
    """(mean SSIM, MSE) of one pair (see :func:`ssim_mse_many`)."""
    return ssim_mse_many([post], ref, ctx=ctx, what=["I_post"])[0]
