"""Depth change of one view on the GPU (host side of ``shaders/depth_change.wgsl``).

Conventions (written once, here):

* A depth value is *valid* when it is finite and > 0; 0 means "no coverage".
  NaN, +/-Inf and negative values are treated as missing too.
* ``dD(p) = |D_pre(p) - D_post(p)|`` when both depths are valid, else 0
  (the public reference implementation's missing-depth rule).
* The histogram has 256 bins spanning ``[lo, hi]`` = [min dD, max dD] of the
  whole image: ``bin(x) = clamp(floor((x - lo) * scale), 0, 255)`` with
  ``scale = float32(256) / float32(hi - lo)`` (0 when ``hi == lo``, putting
  every pixel in bin 0).  All of it is float32 arithmetic, bit-identical to
  the numpy oracle in ``tests/``.
* A pixel is *changed* when ``bin(dD) > t`` for the GHT split ``t`` (a bin
  position, possibly fractional when GHT ties), so the changed mask agrees
  exactly with the histogram split.  In depth units the threshold is the
  upper edge of the last unchanged bin
  (:func:`r360gpu.metrics.ght.threshold_value`).
* A pixel has *no depth after removal* when ``D_post`` is not valid there
  (whatever ``D_pre`` is).  Inside the target mask such a pixel is a
  see-through hole: ``dD`` is 0 there by the missing-depth rule, so it is
  never *changed*; the second pass counts these pixels
  (``n_no_depth_in_mask``) so the hole is reported, not only drawn.

The two GPU passes are split so the host can run GHT (``r360gpu.metrics``)
on the 256 bins in between:
``delta_histogram`` -> GHT -> ``changed_in_mask``.

On CPU adapters (``ctx.kernel_backend("depth_change") == "cpu"``, lavapipe)
depth images given as numpy arrays are measured by the same float32
arithmetic in numpy, without a queue round trip per pass (about 80 ms per
view of small images); results are bit-identical to the kernel's (tests run
both paths against the oracle).  Depths already on the device always take
the kernel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..errors import InputError
from ..gpu.context import BufferRange, DeviceDepth, GpuContext, get_context
from ..gpu.shaders import shader_constants, workgroup_threads

SHADER = "depth_change"
#: The WGSL names of the resources the calls here bind, by position (checked at pipeline creation).
BINDINGS = ("P", "d_pre", "d_post", "delta", "stats", "hist", "m_words", "changed_words", "nd_words")
_SIZES = shader_constants(SHADER)  # the sizes depth_change.wgsl states
QV = _SIZES["QV"]  # vec4s per invocation in delta_minmax / histo
N_BINS = _SIZES["N_BINS"]
_PX_PER_GROUP = {  # pixels one workgroup covers, per entry point (4 pixels a vec4, 32 a changed word)
    "delta_minmax": workgroup_threads(SHADER, "delta_minmax") * QV * 4,
    "histo": workgroup_threads(SHADER, "histo") * QV * 4,
    "histo_private": workgroup_threads(SHADER, "histo_private") * _SIZES["HQ"] * 4,
    "changed": workgroup_threads(SHADER, "changed") * 32,
}


def histogram_entry(ctx: GpuContext) -> str:
    """The histogram flavour for this adapter: shared-memory atomics are cheap
    on GPUs but expensive on CPU adapters, where private per-invocation
    histograms win (measured in bench/bench_depth.py).  The environment
    variable ``R360GPU_HISTOGRAM`` (``histo`` or ``histo_private``) overrides
    the choice."""
    import os

    forced = os.environ.get("R360GPU_HISTOGRAM")
    if forced in ("histo", "histo_private"):
        return forced
    return "histo_private" if ctx.adapter_info.get("adapter_type") == "CPU" else "histo"


@dataclass
class _Chunk:
    r0: int
    r1: int
    delta: object  # GPUBuffer: dD of rows r0:r1, flat, padded to whole 32-pixel words
    no_depth: object = None  # GPUBuffer: bit words of the pixels with no D_post (as the changed words)


@dataclass
class DeltaHistogram:
    """Result of the first pass; keeps dD on the device for the second."""

    height: int
    width: int
    lo: float
    hi: float
    scale: np.float32
    hist: np.ndarray  # (256,) int64
    chunks: list[_Chunk] = field(default_factory=list)
    bins_host: np.ndarray | None = None  # bin(dD) (H, W) uint8 on the host path (no chunks then)
    no_depth_host: np.ndarray | None = None  # (H, W) bool, D_post invalid, on the host path


def bin_scale(lo: float, hi: float) -> np.float32:
    """float32 ``256 / (hi - lo)``, or 0 when the range is empty."""
    span = np.float32(hi) - np.float32(lo)
    if not span > 0:
        return np.float32(0.0)
    return np.float32(np.float32(N_BINS) / span)


def _as_depth(d, what: str):
    if isinstance(d, DeviceDepth):
        return d
    a = np.asarray(d)
    if a.ndim != 2:
        raise InputError(f"{what}: expected a depth image of shape (H, W), got shape {a.shape}")
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise InputError(f"{what}: depth must be numeric, got {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.float32)


def _hw(d) -> tuple[int, int]:
    return (d.height, d.width) if isinstance(d, DeviceDepth) else d.shape


def _rows_per_chunk(ctx: GpuContext, width: int, height: int) -> int:
    # Padding adds up to 31 pixels per chunk; keep a word of slack.
    per_binding = ctx.max_binding_bytes // 4 - 32
    if width > per_binding:
        raise InputError(f"depth rows of {width} pixels do not fit one GPU storage binding")
    rows = max(1, min(height, per_binding // width))
    # Keep every dispatch within two dimensions of workgroups.
    max_px = ctx.max_workgroups * ctx.max_workgroups * min(_PX_PER_GROUP.values())
    return max(1, min(rows, max_px // width))


def _padded(n_px: int, multiple: int = 32) -> int:
    return -(-n_px // multiple) * multiple


def _upload_rows(ctx: GpuContext, d, r0: int, r1: int, slot: str):
    """A buffer with rows r0:r1 of depth image ``d``, flat, padded to whole vec4s."""
    n_px = (r1 - r0) * d.shape[1] if not isinstance(d, DeviceDepth) else (r1 - r0) * d.width
    size = _padded(n_px, 4) * 4
    if isinstance(d, DeviceDepth):
        # Copy the window on the device: the caller's offset and size need not
        # meet binding alignment or the vec4 stride.
        buf = ctx.buffer(size, label="depth")
        enc = ctx.encoder()
        enc.copy_buffer_to_buffer(d.buffer, d.offset + r0 * d.width * 4, buf, 0, n_px * 4)
        ctx.submit(enc)
        return buf
    rows = d[r0:r1].reshape(-1)
    if n_px % 4:
        rows = np.concatenate([rows, np.zeros(4 - n_px % 4, np.float32)])
    # The input is consumed by delta_minmax, which finishes before this call
    # returns, so one reusable buffer per slot and chunk serves every view.
    return ctx.scratch(("depth_change", slot, r0), rows)


def delta_histogram(d_pre, d_post, *, ctx: GpuContext | None = None) -> DeltaHistogram:
    """First pass: dD on the device, its range [lo, hi] and 256-bin histogram.

    ``d_pre``, ``d_post``: float32 (H, W) numpy arrays or :class:`DeviceDepth`.
    """
    return delta_histograms(d_pre, [d_post], ctx=ctx)[0]


_STATS_STRIDE = 256  # bytes between the per-image stats / histograms of a batch (binding offset alignment)


def delta_histograms(d_pre, d_posts, *, ctx: GpuContext | None = None) -> list[DeltaHistogram]:
    """:func:`delta_histogram` of one D_pre against several D_post (the methods
    of a view): D_pre is uploaded once, and every pass of every image is
    recorded in one submission (two waits in all, instead of two per image).
    """
    ctx = ctx or get_context()
    d_pre = _as_depth(d_pre, "D_pre")
    posts = [_as_depth(d, "D_post") for d in d_posts]
    h, w = _hw(d_pre)
    for d in posts:
        if _hw(d) != (h, w):
            raise InputError(f"D_pre is {h}x{w} but D_post is {_hw(d)[0]}x{_hw(d)[1]} (H x W)")
    res = [DeltaHistogram(h, w, 0.0, 0.0, np.float32(0), np.zeros(N_BINS, np.int64)) for _ in posts]
    if h * w == 0 or not posts:
        return res
    if ctx.kernel_backend(SHADER) == "cpu" and not any(isinstance(d, DeviceDepth) for d in (d_pre, *posts)):
        valid_pre = _valid(d_pre)  # once for every method
        return [_delta_histogram_host(d_pre, d, valid_pre) for d in posts]
    n = len(posts)
    rows = _rows_per_chunk(ctx, w, h)
    stride = _STATS_STRIDE
    init = np.zeros((n, stride // 4), np.uint32)
    init[:, 0] = 0xFFFFFFFF
    stats = ctx.buffer(init, label="depth_stats")
    pipe = ctx.pipeline(SHADER, "delta_minmax", bindings=BINDINGS)
    enc = ctx.encoder()
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        n_px = (r1 - r0) * w
        params = ctx.uniform(n_px, 0, 0, 0, 0.0, 0.0, 0.0, 0)
        b_pre = _upload_rows(ctx, d_pre, r0, r1, "pre")
        for k, d in enumerate(posts):
            delta = ctx.buffer(_padded(n_px) * 4, label="delta")
            no_depth = ctx.buffer(_padded(n_px) // 8, label="no_depth_words")  # new buffers are zeroed
            ctx.dispatch(
                enc, pipe,
                [params, b_pre, _upload_rows(ctx, d, r0, r1, ("post", k)), delta,
                 BufferRange(stats, k * stride, 16), None, None, None, no_depth],
                ctx.grid(math.ceil(n_px / _PX_PER_GROUP["delta_minmax"])),
            )
            res[k].chunks.append(_Chunk(r0, r1, delta, no_depth))
    ctx.submit(enc)
    st = ctx.read(stats, np.uint32, n * stride // 4).reshape(n, -1)
    hist = ctx.buffer(n * stride * 4, label="hist")  # 256 u32 per image, stride-aligned
    entry = histogram_entry(ctx)
    pipe = ctx.pipeline(SHADER, entry, bindings=BINDINGS)
    enc = ctx.encoder()
    for k, r in enumerate(res):
        r.lo = float(np.uint32(st[k, 0]).view(np.float32))
        r.hi = float(np.uint32(st[k, 1]).view(np.float32))
        r.scale = bin_scale(r.lo, r.hi)
        for c in r.chunks:
            n_px = (c.r1 - c.r0) * w
            params = ctx.uniform(n_px, 0, 0, 0, np.float32(r.lo), r.scale, 0.0, 0)
            groups = ctx.grid(math.ceil(n_px / _PX_PER_GROUP[entry]))
            ctx.dispatch(enc, pipe, [params, None, None, c.delta, None,
                                     BufferRange(hist, k * N_BINS * 4, N_BINS * 4)], groups)
    ctx.submit(enc)
    hs = ctx.read(hist, np.uint32, n * N_BINS).reshape(n, N_BINS)
    for k, r in enumerate(res):
        r.hist = hs[k].astype(np.int64)
    return res


def _valid(d: np.ndarray) -> np.ndarray:
    return (d > 0) & (d < np.float32(np.inf))  # finite and > 0 (NaN compares False)


def no_depth(d) -> np.ndarray:
    """bool (H, W): no depth at the pixel, by the rule above (not finite or <= 0 once in float32),
    for a host depth image of any real dtype (a PNG's uint8 levels too: 0 is missing)."""
    with np.errstate(over="ignore"):
        return ~_valid(np.asarray(d, dtype=np.float32))


def _delta_histogram_host(d_pre: np.ndarray, d_post: np.ndarray, valid_pre: np.ndarray) -> DeltaHistogram:
    """The first pass in numpy, with the kernel's float32 operations; keeps the bins for the second."""
    h, w = d_pre.shape
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf: zeroed below with the other missing pixels
        delta = np.subtract(d_pre, d_post)
    np.abs(delta, out=delta)
    valid_post = _valid(d_post)
    invalid = np.logical_and(valid_pre, valid_post)
    np.logical_not(invalid, out=invalid)
    np.copyto(delta, 0, where=invalid)
    lo, hi = float(delta.min()), float(delta.max())
    scale = bin_scale(lo, hi)
    bins = _bins(delta, lo, scale)
    return DeltaHistogram(h, w, lo, hi, scale, _histogram(bins), bins_host=bins,
                          no_depth_host=np.logical_not(valid_post, out=valid_post))


#: Pixels per cv2.calcHist call: its float32 counts are exact integers up to 2^24.
_HIST_CHUNK = 1 << 24


def _histogram(bins: np.ndarray) -> np.ndarray:
    """(256,) int64 counts of a uint8 array (cv2.calcHist counts bytes as they are; np.bincount widens them
    to intp first)."""
    flat = bins.reshape(-1)
    out = np.zeros(N_BINS, np.int64)
    for i in range(0, flat.size, _HIST_CHUNK):
        part = flat[i : i + _HIST_CHUNK].reshape(-1, 1)
        out += cv2.calcHist([part], [0], None, [N_BINS], [0, N_BINS]).reshape(-1).astype(np.int64)
    return out


def _bins(delta: np.ndarray, lo: float, scale: np.float32) -> np.ndarray:
    """clamp(floor((dD - lo) * scale), 0, 255) as uint8, in float32 like the kernel."""
    x = np.subtract(delta, np.float32(lo), dtype=np.float32)
    x *= scale
    np.floor(x, out=x)
    np.clip(x, 0, N_BINS - 1, out=x)
    return x.astype(np.uint8)


@dataclass
class ChangedResult:
    """Second pass: ``changed`` bool (H, W); counts inside the target mask: changed pixels, all
    pixels, and pixels with no depth after removal (a see-through hole, never changed)."""

    changed: np.ndarray
    n_changed_in_mask: int
    n_mask: int
    n_no_depth_in_mask: int = 0


def changed_in_mask(stage: DeltaHistogram, mask, t: float, *, ctx: GpuContext | None = None) -> ChangedResult:
    """Changed pixels (``bin(dD) > t``) and how many fall inside ``mask`` (H, W)."""
    return changed_in_masks([stage], mask, [t], ctx=ctx)[0]


def _split_f32(t: float) -> np.float32:
    """The split as the kernel compares it.  Bins are whole numbers, so
    ``bin > t`` is ``bin > floor(t)``; passing floor(t) (clamped to [-1, 255])
    keeps a t such as 254.99999999999997 from rounding up to 255 in float32."""
    t = float(t)
    if math.isnan(t):
        return np.float32(N_BINS - 1)  # bin > NaN is never true
    return np.float32(min(max(math.floor(t) if math.isfinite(t) else t, -1.0), float(N_BINS - 1)))


def changed_in_masks(stages, mask, ts, *, ctx: GpuContext | None = None) -> list[ChangedResult]:
    """:func:`changed_in_mask` of several first-pass results (one view's methods)
    against one target mask, in one submission; the mask is uploaded once."""
    ctx = ctx or get_context()
    stages, ts = list(stages), list(ts)
    if not stages:
        return []
    h, w = stages[0].height, stages[0].width
    m = np.asarray(mask)
    if m.shape != (h, w):
        raise InputError(f"target mask is {m.shape[0]}x{m.shape[1]} but the depth images are {h}x{w} (H x W)")
    for s in stages:
        if (s.height, s.width) != (h, w):
            raise InputError(f"depth images of one batch differ in size: {h}x{w} vs {s.height}x{s.width} (H x W)")
    out = [ChangedResult(np.zeros((h, w), bool), 0, 0) for _ in stages]
    if h * w == 0:
        return out
    if all(s.bins_host is not None for s in stages):
        inside = m != 0
        n_mask = int(np.count_nonzero(inside))
        for k, (stage, t) in enumerate(zip(stages, ts)):
            changed = stage.bins_host > _split_f32(t)
            out[k] = ChangedResult(changed, int(np.count_nonzero(changed & inside)), n_mask,
                                   int(np.count_nonzero(stage.no_depth_host & inside)))
        return out
    n = len(stages)
    stride = _STATS_STRIDE
    stats = ctx.buffer(np.zeros(n * stride // 4, np.uint32), label="changed_stats")
    pipe = ctx.pipeline(SHADER, "changed", bindings=BINDINGS)
    pending = []
    enc = ctx.encoder()
    m_bufs = {}
    for k, (stage, t) in enumerate(zip(stages, ts)):
        for c in stage.chunks:
            n_px = (c.r1 - c.r0) * w
            n_words = _padded(n_px) // 32
            if c.r0 not in m_bufs:
                m_words = np.zeros(n_words * 4, np.uint8)
                packed = np.packbits(m[c.r0 : c.r1].reshape(-1), bitorder="little")
                m_words[: packed.size] = packed
                m_bufs[c.r0] = ctx.buffer(m_words.view(np.uint32), label="mask_words")
            words = ctx.buffer(n_words * 4, label="changed_words")
            params = ctx.uniform(n_px, 0, 0, 0, np.float32(stage.lo), stage.scale, _split_f32(t), 0)
            ctx.dispatch(
                enc, pipe,
                [params, None, None, c.delta, BufferRange(stats, k * stride, 32), None, m_bufs[c.r0], words,
                 c.no_depth],
                ctx.grid(math.ceil(n_words / workgroup_threads(SHADER, "changed"))),
            )
            pending.append((k, c, words, n_words))
    ctx.submit(enc)
    for k, c, words, n_words in pending:
        bits = np.unpackbits(ctx.read(words, np.uint8, n_words * 4), bitorder="little")
        out[k].changed[c.r0 : c.r1] = bits[: (c.r1 - c.r0) * w].view(bool).reshape(c.r1 - c.r0, w)
    st = ctx.read(stats, np.uint32, n * stride // 4).reshape(n, -1)
    for k in range(n):
        out[k].n_changed_in_mask, out[k].n_mask, out[k].n_no_depth_in_mask = (int(st[k, 2]), int(st[k, 3]),
                                                                               int(st[k, 4]))
    return out
