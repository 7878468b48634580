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

The two GPU passes are split so the host can run GHT (``r360gpu.metrics``)
on the 256 bins in between:
``delta_histogram`` -> GHT -> ``changed_in_mask``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..gpu.context import GpuContext, get_context
from .mask_iou import pack_bits, row_words

SHADER = "depth_change"
WG = 256
N_BINS = 256


@dataclass
class DeviceDepth:
    """A depth image already on the device: ``height x width`` float32,
    row-major, starting at byte ``offset`` of ``buffer`` (STORAGE usage)."""

    buffer: object
    height: int
    width: int
    offset: int = 0


@dataclass
class _Chunk:
    r0: int
    r1: int
    delta: object  # GPUBuffer f32 (r1-r0) x width


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
    _stats: object = None


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
    per_binding = ctx.max_binding_bytes // 4
    if width > per_binding:
        raise InputError(f"depth rows of {width} pixels do not fit one GPU storage binding")
    rows = max(1, min(height, per_binding // width))
    # One invocation per pixel: keep the dispatch within two dimensions.
    max_px = ctx.max_workgroups * ctx.max_workgroups * WG
    return max(1, min(rows, max_px // width))


def _bind_rows(ctx: GpuContext, d, r0: int, r1: int):
    """A buffer (or window) holding rows r0:r1 of depth image ``d``."""
    from ..gpu.context import BufferRange

    if isinstance(d, DeviceDepth):
        start = d.offset + r0 * d.width * 4
        size = (r1 - r0) * d.width * 4
        align = ctx.storage_offset_alignment
        if start % align:
            # Unaligned window: copy the rows into a fresh buffer on the device.
            buf = ctx.buffer(size)
            enc = ctx.encoder()
            enc.copy_buffer_to_buffer(d.buffer, start, buf, 0, size)
            ctx.submit(enc)
            return buf
        return BufferRange(d.buffer, start, size)
    return ctx.buffer(d[r0:r1], label="depth")


def delta_histogram(d_pre, d_post, *, ctx: GpuContext | None = None) -> DeltaHistogram:
    """First pass: dD on the device, its range [lo, hi] and 256-bin histogram.

    ``d_pre``, ``d_post``: float32 (H, W) numpy arrays or :class:`DeviceDepth`.
    """
    ctx = ctx or get_context()
    d_pre, d_post = _as_depth(d_pre, "D_pre"), _as_depth(d_post, "D_post")
    h, w = _hw(d_pre)
    if _hw(d_post) != (h, w):
        raise InputError(f"D_pre is {h}x{w} but D_post is {_hw(d_post)[0]}x{_hw(d_post)[1]} (H x W)")
    res = DeltaHistogram(h, w, 0.0, 0.0, np.float32(0), np.zeros(N_BINS, np.int64))
    if h * w == 0:
        return res
    rows = _rows_per_chunk(ctx, w, h)
    stats = ctx.buffer(np.array([0xFFFFFFFF, 0, 0, 0], np.uint32), label="depth_stats")
    pipe = ctx.pipeline(SHADER, "delta_minmax")
    enc = ctx.encoder()
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        delta = ctx.buffer((r1 - r0) * w * 4, label="delta")
        params = ctx.uniform(r1 - r0, w, row_words(w), 0, 0.0, 0.0, 0.0, 0)
        ctx.dispatch(
            enc, pipe,
            [params, _bind_rows(ctx, d_pre, r0, r1), _bind_rows(ctx, d_post, r0, r1), delta, stats],
            ctx.grid(math.ceil((r1 - r0) * w / WG)),
        )
        res.chunks.append(_Chunk(r0, r1, delta))
    ctx.submit(enc)
    lo_bits, hi_bits = ctx.read(stats, np.uint32, 2)
    res.lo = float(np.uint32(lo_bits).view(np.float32))
    res.hi = float(np.uint32(hi_bits).view(np.float32))
    res.scale = bin_scale(res.lo, res.hi)
    hist = ctx.buffer(N_BINS * 4, label="hist")
    pipe = ctx.pipeline(SHADER, "histo")
    enc = ctx.encoder()
    for c in res.chunks:
        params = ctx.uniform(c.r1 - c.r0, w, row_words(w), 0, np.float32(res.lo), res.scale, 0.0, 0)
        ctx.dispatch(enc, pipe, [params, None, None, c.delta, None, hist], ctx.grid(math.ceil((c.r1 - c.r0) * w / WG)))
    ctx.submit(enc)
    res.hist = ctx.read(hist, np.uint32, N_BINS).astype(np.int64)
    res._stats = stats
    return res


@dataclass
class ChangedResult:
    """Second pass: ``changed`` bool (H, W); counts inside the target mask."""

    changed: np.ndarray
    n_changed_in_mask: int
    n_mask: int


def changed_in_mask(stage: DeltaHistogram, mask, t: float, *, ctx: GpuContext | None = None) -> ChangedResult:
    """Changed pixels (``bin(dD) > t``) and how many fall inside ``mask`` (H, W)."""
    ctx = ctx or get_context()
    h, w = stage.height, stage.width
    m = np.asarray(mask)
    if m.shape != (h, w):
        raise InputError(f"target mask is {m.shape[0]}x{m.shape[1]} but the depth images are {h}x{w} (H x W)")
    rw = row_words(w)
    changed = np.zeros((h, rw), np.uint32)
    if h * w == 0:
        return ChangedResult(np.zeros((h, w), bool), 0, 0)
    m_packed = pack_bits(m[None])[0]
    stats = ctx.buffer(np.zeros(4, np.uint32), label="changed_stats")
    pipe = ctx.pipeline(SHADER, "changed")
    outs = []
    enc = ctx.encoder()
    for c in stage.chunks:
        nr = c.r1 - c.r0
        words = ctx.buffer(nr * rw * 4, label="changed_words")
        params = ctx.uniform(nr, w, rw, 0, np.float32(stage.lo), stage.scale, np.float32(t), 0)
        mw = ctx.buffer(np.ascontiguousarray(m_packed[c.r0 : c.r1]), label="mask_words")
        ctx.dispatch(
            enc, pipe, [params, None, None, c.delta, stats, None, mw, words], ctx.grid(math.ceil(nr * rw / WG))
        )
        outs.append((c, words))
    ctx.submit(enc)
    for c, words in outs:
        changed[c.r0 : c.r1] = ctx.read(words, np.uint32, (c.r1 - c.r0) * rw).reshape(c.r1 - c.r0, rw)
    s = ctx.read(stats, np.uint32, 4)
    bits = np.unpackbits(changed.view(np.uint8).reshape(h, rw * 4), axis=1, bitorder="little")[:, :w]
    return ChangedResult(bits.astype(bool), int(s[2]), int(s[3]))
