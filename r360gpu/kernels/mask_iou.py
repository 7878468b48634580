"""Batched mask IoU on the GPU (host side of ``shaders/mask_iou.wgsl``).

Masks are bit-packed, 32 pixels per ``u32``, row by row: bit ``b`` of word
``c`` of row ``r`` is pixel ``(r, 32 c + b)``; each row is padded to whole
words (``row_words = ceil(W / 32)``).  Every mask also carries the bounding box
of its set bits in (row, word) units, so a pair of masks only visits the
overlap of their boxes.  Packing host arrays happens on the CPU with
``np.packbits`` (measured faster than uploading bytes and packing on the GPU:
see ``bench/bench_mask_iou.py``); masks that already live on the device
(:class:`DeviceMasks`) are packed by the ``pack`` kernel instead.

Intersections and areas are computed on the GPU; IoU is ``inter / union``
with ``IoU = 0`` where the union is empty.  Every stack is split into chunks
whose buffers fit one storage binding, so any number and size of masks works.

On CPU adapters (``ctx.kernel_backend("mask_iou") == "cpu"``, lavapipe) a
stack packed on the host is never uploaded: intersections and unions are
counted on the packed words with numpy (``np.bitwise_count`` over the box of
each mask of A), the same integers the kernel counts (tests run both paths
against the numpy oracle).  Uploads happen on first use by a GPU kernel.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..gpu.context import BufferRange, GpuContext, get_context
from ..gpu.shaders import shader_constant
from ..util.memo import ByIdentity

SHADER = "mask_iou"
#: The WGSL names of the resources the calls here bind, by position (checked at pipeline creation).
BINDINGS = ("P", "a_words", "a_boxes", "b_words", "b_boxes", "out", "out_boxes")
_HOST_COUNTS = hasattr(np, "bitwise_count")  # numpy >= 2; else intersections always run the kernel
WG = shader_constant(SHADER, "WG")  # workgroup size of every entry point in mask_iou.wgsl
_RANGES_EMPTY = (0, 0)


@dataclass
class DeviceMasks:
    """A stack of masks already on the device: ``n`` masks of ``height x width``
    pixels, one ``u32`` per pixel (0 = outside, non-zero = inside), row-major,
    mask after mask, starting at byte ``offset`` of ``buffer``.  The buffer
    needs the ``STORAGE`` usage."""

    buffer: object
    n: int
    height: int
    width: int
    offset: int = 0


@dataclass
class BitMasks:
    """A stack already bit-packed on the host: ``words`` (N, H, row_words(width))
    uint32 in the layout of :func:`pack_bits` (bits past ``width`` zero), e.g.
    the boundary sweep's perturbed targets (:mod:`r360gpu.kernels.morph`)."""

    words: np.ndarray
    width: int


@dataclass
class PackedChunk:
    """Masks ``k0:k1`` restricted to rows ``r0:r1``, on the device."""

    k0: int
    k1: int
    r0: int
    r1: int
    words: object  # GPUBuffer: (k1-k0) x (r1-r0) x row_words u32
    boxes: object  # GPUBuffer: (k1-k0) x vec4<u32> (row0, row1, word0, word1), rows relative to r0
    boxes_host: np.ndarray  # (k1-k0, 4) uint32, same values


@dataclass
class PackedMasks:
    """A bit-packed mask stack on the device, split into binding-sized chunks."""

    n: int
    height: int
    width: int
    chunks: list[PackedChunk] = field(default_factory=list)  # uploaded on first GPU use (see device_chunks)
    areas_host: np.ndarray | None = None  # (n,) int64 when counted at packing (saves a GPU round trip)
    words_host: np.ndarray | None = None  # (n, H, row_words) uint32 when packed on the host
    boxes_host: np.ndarray | None = None  # (n, 4) uint32 whole-frame boxes, with words_host

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.n, self.height, self.width)

    @property
    def row_words(self) -> int:
        return row_words(self.width)


@dataclass
class MaskIoU:
    """Overlap of stacks A (``N`` masks) and B (``M`` masks).

    ``intersection`` (N, M) int64 pixel counts, ``area_a`` (N,) int64,
    ``area_b`` (M,) int64, ``iou`` (N, M) float64 in [0, 1] (0 where both
    masks are empty)."""

    intersection: np.ndarray
    area_a: np.ndarray
    area_b: np.ndarray
    iou: np.ndarray


def row_words(width: int) -> int:
    return max(1, math.ceil(width / 32))


# -- packing ---------------------------------------------------------------
def _as_stack(masks, what: str) -> np.ndarray:
    m = np.asarray(masks)
    if m.ndim == 2:
        m = m[None]
    if m.ndim != 3:
        raise InputError(f"{what}: expected a mask stack of shape (N, H, W), got shape {m.shape}")
    if m.dtype == np.bool_:
        return m.view(np.uint8)
    if np.issubdtype(m.dtype, np.floating):
        if np.isnan(m).any():
            raise InputError(f"{what}: masks contain NaN (binary masks expected)")
        return (m != 0).view(np.uint8)
    if not np.issubdtype(m.dtype, np.integer):
        raise InputError(f"{what}: masks must be bool or integer, got {m.dtype}")
    if m.dtype.itemsize != 1:
        return (m != 0).view(np.uint8)
    return m.view(np.uint8)


def pack_bits(masks) -> np.ndarray:
    """Bit-pack an (N, H, W) stack on the CPU -> (N, H, row_words) ``uint32``.

    Any non-zero value is "inside".  This is the numpy oracle of the layout.
    """
    m = _as_stack(masks, "masks")
    n, h, w = m.shape
    rw = row_words(w)
    if n == 0 or h == 0:
        return np.zeros((n, h, rw), np.uint32)
    m = np.ascontiguousarray(m)
    if w % 32 == 0:
        # Rows end on word boundaries: one flat packbits over the whole stack.
        flat = np.packbits(m.reshape(-1), bitorder="little")
        return flat.view("<u4").reshape(n, h, rw)
    rows = np.packbits(m.reshape(n * h, w), axis=1, bitorder="little")
    out = np.zeros((n * h, rw * 4), np.uint8)
    out[:, : rows.shape[1]] = rows
    return out.view("<u4").reshape(n, h, rw)


def _boxes(packed: np.ndarray) -> np.ndarray:
    """(N, 4) uint32 (row0, row1, word0, word1) of each packed mask's set bits."""
    n, h, rw = packed.shape
    out = np.zeros((n, 4), np.uint32)
    if n == 0:
        return out
    nz = packed != 0
    rows = nz.any(axis=2)
    cols = nz.any(axis=1)
    has = rows.any(axis=1)
    out[:, 0] = np.where(has, rows.argmax(axis=1), 0)
    out[:, 1] = np.where(has, h - rows[:, ::-1].argmax(axis=1), 0)
    out[:, 2] = np.where(has, cols.argmax(axis=1), 0)
    out[:, 3] = np.where(has, rw - cols[:, ::-1].argmax(axis=1), 0)
    return out


def _popcount(packed: np.ndarray) -> np.ndarray | None:
    """(N,) int64 set bits per mask with numpy >= 2's vectorised popcount; None
    on older numpy (the GPU area kernel counts them then)."""
    if not hasattr(np, "bitwise_count"):
        return None
    n = packed.shape[0]
    if n == 0 or packed.size == 0:
        return np.zeros(n, np.int64)
    return np.bitwise_count(packed.reshape(n, -1)).sum(axis=1, dtype=np.int64)


def _clip_boxes(boxes: np.ndarray, r0: int, r1: int) -> np.ndarray:
    """Boxes restricted to rows r0:r1 and made relative to r0 (empty -> zeros)."""
    b = boxes.astype(np.int64).copy()
    b[:, 0] = np.clip(b[:, 0] - r0, 0, r1 - r0)
    b[:, 1] = np.clip(b[:, 1] - r0, 0, r1 - r0)
    empty = (b[:, 1] <= b[:, 0]) | (b[:, 3] <= b[:, 2])
    b[empty] = 0
    return b.astype(np.uint32)


def _layout(ctx: GpuContext, n: int, h: int, rw: int) -> tuple[int, int]:
    """(masks per chunk, rows per chunk) so one chunk's words fit a binding."""
    per_binding = ctx.max_binding_bytes // 4
    if rw > per_binding:
        raise InputError(f"mask rows of {rw * 32} pixels do not fit one GPU storage binding")
    rchunk = max(1, min(h, per_binding // rw))
    kchunk = max(1, min(n, per_binding // (rchunk * rw), ctx.max_workgroups)) if n else 1
    return kchunk, rchunk


def pack(masks, *, ctx: GpuContext | None = None) -> PackedMasks:
    """Upload a stack to the device as :class:`PackedMasks`.

    ``masks``: (N, H, W) or (H, W) bool/integer numpy array, a
    :class:`BitMasks` or :class:`DeviceMasks`, or an existing
    :class:`PackedMasks` (returned as is).
    """
    if isinstance(masks, PackedMasks):
        return masks
    ctx = ctx or get_context()
    if isinstance(masks, DeviceMasks):
        return _pack_device(masks, ctx)
    if isinstance(masks, BitMasks):
        packed, w = np.ascontiguousarray(masks.words, np.uint32), int(masks.width)
        if packed.ndim != 3 or packed.shape[2] != row_words(w):
            raise InputError(f"BitMasks: words of shape {packed.shape} do not hold rows of {w} pixels")
    else:
        packed = pack_bits(masks)
        w = np.shape(masks)[-1]
    n, h, _ = packed.shape
    out = PackedMasks(n, int(h), int(w), areas_host=_popcount(packed), words_host=packed, boxes_host=_boxes(packed))
    if ctx.kernel_backend(SHADER) == "gpu":
        device_chunks(out, ctx)
    return out


def take(p: PackedMasks, index, masks=None, *, ctx: GpuContext | None = None) -> PackedMasks:
    """Masks ``index`` (int indices, in that order) of a packed stack, equal to packing ``masks[index]``.

    From the host words when the stack has them (no second pass over the pixels); otherwise
    ``masks`` (the stack ``p`` was packed from) is indexed and packed.
    """
    index = np.asarray(index, np.int64).reshape(-1)
    if p.words_host is None:
        if masks is None:
            raise ValueError("take: a stack packed on the device needs the masks it was packed from")
        return pack(np.asarray(masks)[index], ctx=ctx)
    ctx = ctx or get_context()
    areas = p.areas_host[index] if p.areas_host is not None else None
    out = PackedMasks(int(index.shape[0]), p.height, p.width, areas_host=areas,
                      words_host=np.ascontiguousarray(p.words_host[index]), boxes_host=p.boxes_host[index])
    if ctx.kernel_backend(SHADER) == "gpu":
        device_chunks(out, ctx)
    return out


class PackMemo:
    """Each stack packed once while the memo lives (a view's worth of work), by identity
    (:class:`~r360gpu.util.memo.ByIdentity`); the arrays must not change meanwhile (probe outputs
    do not).  Anything but a numpy array given to :meth:`pack` is packed each time.
    """

    def __init__(self, ctx: GpuContext | None = None):
        self.ctx = ctx
        self._memo = ByIdentity()

    def pack(self, masks) -> PackedMasks:
        if not isinstance(masks, np.ndarray):
            return pack(masks, ctx=self.ctx)
        return self._memo.get(pack, (masks,), lambda: pack(masks, ctx=self.ctx))


def device_chunks(p: PackedMasks, ctx: GpuContext) -> list[PackedChunk]:
    """The stack's binding-sized chunks on the device, uploaded from the host words on first use."""
    if p.chunks or p.words_host is None or p.n == 0:
        return p.chunks
    packed, boxes, n, h = p.words_host, p.boxes_host, p.n, p.height
    kchunk, rchunk = _layout(ctx, n, h, p.row_words)
    for k0 in range(0, n, kchunk):
        k1 = min(n, k0 + kchunk)
        for r0 in range(0, h, rchunk):
            r1 = min(h, r0 + rchunk)
            bx = _clip_boxes(boxes[k0:k1], r0, r1)
            words = packed[k0:k1] if (r0, r1) == (0, h) else np.ascontiguousarray(packed[k0:k1, r0:r1])
            p.chunks.append(
                PackedChunk(k0, k1, r0, r1, ctx.buffer(words, label="mask_words"), ctx.buffer(bx, label="mask_boxes"), bx)
            )
    return p.chunks


def _pack_device(dm: DeviceMasks, ctx: GpuContext) -> PackedMasks:
    n, h, w = int(dm.n), int(dm.height), int(dm.width)
    hw = h * w
    rw = row_words(w)
    out = PackedMasks(n, h, w)
    if n == 0 or hw == 0:
        return out
    need = dm.offset + n * hw * 4
    if dm.offset % 4 or dm.buffer.size < need:
        raise InputError(
            f"DeviceMasks: buffer of {dm.buffer.size} bytes at offset {dm.offset} cannot hold {n}x{h}x{w} u32 masks"
        )
    align = ctx.storage_offset_alignment
    # The input window (u32 per pixel) must fit one binding as well.
    span = (ctx.max_binding_bytes - align) // 4
    kchunk, rchunk = _layout(ctx, n, h, rw)
    rchunk = max(1, min(rchunk, span // w))
    if rchunk < h:
        kchunk = 1
    else:
        kchunk = max(1, min(kchunk, (span - hw) // hw + 1))
    pipe = ctx.pipeline(SHADER, "pack", bindings=BINDINGS)
    for k0 in range(0, n, kchunk):
        k1 = min(n, k0 + kchunk)
        for r0 in range(0, h, rchunk):
            r1 = min(h, r0 + rchunk)
            nk, nr = k1 - k0, r1 - r0
            first = dm.offset // 4 + k0 * hw + r0 * w  # element of (k0, r0, 0)
            last = dm.offset // 4 + (k1 - 1) * hw + r1 * w  # one past the window
            start = first * 4 - (first * 4) % align
            size = min(last * 4 - start, dm.buffer.size - start)
            words = ctx.buffer(nk * nr * rw * 4, label="mask_words")
            boxes = ctx.buffer(np.tile(np.array([nr, 0, rw, 0], np.uint32), nk), label="mask_boxes")
            params = ctx.uniform(nk, 0, nr, rw, first - start // 4, w, hw, 0)
            groups = ctx.grid(math.ceil(nk * nr * rw / WG))
            ctx.run(pipe, [params, None, None, BufferRange(dm.buffer, start, size), None, words, boxes], groups)
            bx = ctx.read(boxes, np.uint32, 4 * nk).reshape(nk, 4)
            bx = _clip_boxes(bx, 0, nr)  # zero the boxes of empty masks
            ctx.write(boxes, bx)
            out.chunks.append(PackedChunk(k0, k1, r0, r1, words, boxes, bx))
    return out


# -- kernels ---------------------------------------------------------------
def _check_pair(a: PackedMasks, b: PackedMasks) -> None:
    if (a.height, a.width) != (b.height, b.width):
        raise InputError(
            f"mask stacks differ in size: {a.height}x{a.width} (H x W) vs {b.height}x{b.width}"
        )


def areas(masks, *, ctx: GpuContext | None = None) -> np.ndarray:
    """Pixel count of every mask: (N,) int64."""
    ctx = ctx or get_context()
    p = pack(masks, ctx=ctx)
    if p.areas_host is not None:
        return p.areas_host.copy()
    out = np.zeros(p.n, np.int64)
    pipe = ctx.pipeline(SHADER, "area", bindings=BINDINGS)
    for c in device_chunks(p, ctx):
        nk = c.k1 - c.k0
        buf = ctx.buffer(nk * 4)
        params = ctx.uniform(nk, 0, c.r1 - c.r0, p.row_words, 0, 0, 0, 0)
        ctx.run(pipe, [params, c.words, c.boxes, None, None, buf], ctx.grid(nk))
        out[c.k0 : c.k1] += ctx.read(buf, np.uint32, nk)
    return out


def intersections(a, b, *, ctx: GpuContext | None = None) -> np.ndarray:
    """|a_i AND b_j| for every pair: (N, M) int64."""
    ctx = ctx or get_context()
    pa, pb = pack(a, ctx=ctx), pack(b, ctx=ctx)
    _check_pair(pa, pb)
    inter = np.zeros((pa.n, pb.n), np.int64)
    if pa.n == 0 or pb.n == 0:
        return inter
    if _HOST_COUNTS and ctx.kernel_backend(SHADER) == "cpu" and pa.words_host is not None \
            and pb.words_host is not None:
        return _intersections_host(pa, pb, inter)
    device_chunks(pa, ctx), device_chunks(pb, ctx)
    pipe = ctx.pipeline(SHADER, "intersect", bindings=BINDINGS)
    max_out = ctx.max_binding_bytes // 4
    pending = []
    enc = ctx.encoder()
    queued = 0
    for ca in pa.chunks:
        for cb in pb.chunks:
            if (ca.r0, ca.r1) != (cb.r0, cb.r1):
                continue
            # Skip chunk pairs whose boxes cannot overlap.
            if not _any_overlap(ca.boxes_host, cb.boxes_host):
                continue
            na, nb = ca.k1 - ca.k0, cb.k1 - cb.k0
            # Split rows so the output of one dispatch fits one binding.
            rows = max(1, min(na, max_out // nb))
            for r0 in range(0, na, rows):
                r1 = min(na, r0 + rows)
                nr = r1 - r0
                out = ctx.buffer(nr * nb * 4)
                params = ctx.uniform(nr, nb, ca.r1 - ca.r0, pa.row_words, r0, 0, 0, 0)
                ctx.dispatch(enc, pipe, [params, ca.words, ca.boxes, cb.words, cb.boxes, out], (nb, nr, 1))
                pending.append((out, ca.k0 + r0, ca.k0 + r1, cb.k0, cb.k1))
                queued += nr * nb
                if queued > (1 << 22):  # bound the memory held by queued outputs
                    ctx.submit(enc)
                    _collect(ctx, pending, inter)
                    enc, queued = ctx.encoder(), 0
    ctx.submit(enc)
    _collect(ctx, pending, inter)
    return inter


def _intersections_host(pa: PackedMasks, pb: PackedMasks, inter: np.ndarray) -> np.ndarray:
    """The kernel's counts from the host words: per mask of A, over its box, with every
    mask of B whose box meets it."""
    a, b = pa.words_host, pb.words_host
    ba, bb = pa.boxes_host.astype(np.int64), pb.boxes_host.astype(np.int64)
    b_has = (bb[:, 1] > bb[:, 0]) & (bb[:, 3] > bb[:, 2])
    for i in range(pa.n):
        r0, r1, c0, c1 = ba[i]
        if r1 <= r0 or c1 <= c0:
            continue
        js = np.flatnonzero(b_has & (bb[:, 0] < r1) & (bb[:, 1] > r0) & (bb[:, 2] < c1) & (bb[:, 3] > c0))
        if js.size == 0:
            continue
        both = a[i, r0:r1, c0:c1] & (b[js, r0:r1, c0:c1] if js.size < pb.n else b[:, r0:r1, c0:c1])
        inter[i, js] = np.bitwise_count(both).sum(axis=(1, 2), dtype=np.int64)
    return inter


def _any_overlap(ba: np.ndarray, bb: np.ndarray) -> bool:
    """Whether any box of ``ba`` can meet any box of ``bb`` (a cheap bound)."""
    ba = ba[(ba[:, 1] > ba[:, 0]) & (ba[:, 3] > ba[:, 2])]
    bb = bb[(bb[:, 1] > bb[:, 0]) & (bb[:, 3] > bb[:, 2])]
    if not len(ba) or not len(bb):
        return False
    rows = max(int(ba[:, 0].min()), int(bb[:, 0].min())) < min(int(ba[:, 1].max()), int(bb[:, 1].max()))
    cols = max(int(ba[:, 2].min()), int(bb[:, 2].min())) < min(int(ba[:, 3].max()), int(bb[:, 3].max()))
    return rows and cols


def _collect(ctx, pending, inter) -> None:
    for out, i0, i1, j0, j1 in pending:
        inter[i0:i1, j0:j1] += ctx.read(out, np.uint32, (i1 - i0) * (j1 - j0)).reshape(i1 - i0, j1 - j0)
    pending.clear()


def iou_from_counts(inter: np.ndarray, area_a: np.ndarray, area_b: np.ndarray) -> np.ndarray:
    """IoU from counts (float64), 0 where the union is empty."""
    inter = np.asarray(inter, np.float64)
    union = np.asarray(area_a, np.float64)[:, None] + np.asarray(area_b, np.float64)[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def mask_iou(a, b, *, ctx: GpuContext | None = None) -> MaskIoU:
    """IoU matrix between stack ``a`` (N, H, W) and stack ``b`` (M, H, W).

    Inputs: numpy bool/integer arrays (non-zero = inside), `DeviceMasks`
    or `PackedMasks` (pack once with `pack` to reuse a stack).
    N = 0 or M = 0 gives empty matrices; different H x W is an InputError.
    """
    ctx = ctx or get_context()
    pa, pb = pack(a, ctx=ctx), pack(b, ctx=ctx)
    _check_pair(pa, pb)
    inter = intersections(pa, pb, ctx=ctx)
    aa, ab = areas(pa, ctx=ctx), areas(pb, ctx=ctx)
    return MaskIoU(inter, aa, ab, iou_from_counts(inter, aa, ab))


def iou_with_target(masks, target, *, ctx: GpuContext | None = None) -> np.ndarray:
    """IoU of every mask in ``masks`` (N, H, W) with one ``target`` (H, W): (N,) float64."""
    t = target if isinstance(target, (PackedMasks, DeviceMasks)) else np.asarray(target)
    if isinstance(t, np.ndarray) and t.ndim != 2:
        raise InputError(f"target mask must be 2-D (H, W), got shape {t.shape}")
    return mask_iou(masks, t, ctx=ctx).iou[:, 0]


def union(masks, *, ctx: GpuContext | None = None) -> np.ndarray:
    """Pixel-wise OR of a stack: bool (H, W) (all False for N = 0)."""
    ctx = ctx or get_context()
    p = pack(masks, ctx=ctx)
    rw = p.row_words
    if ctx.kernel_backend(SHADER) == "cpu" and p.words_host is not None:
        words = np.bitwise_or.reduce(p.words_host, axis=0) if p.n else np.zeros((p.height, rw), np.uint32)
        return unpack_bits(words[None], p.width)[0]
    words = np.zeros((p.height, rw), np.uint32)
    pipe = ctx.pipeline(SHADER, "union_or", bindings=BINDINGS)
    for c in device_chunks(p, ctx):
        nk, nr = c.k1 - c.k0, c.r1 - c.r0
        buf = ctx.buffer(nr * rw * 4)
        params = ctx.uniform(nk, 0, nr, rw, 0, 0, 0, 0)
        ctx.run(pipe, [params, c.words, c.boxes, None, None, buf], ctx.grid(math.ceil(nr * rw / WG)))
        words[c.r0 : c.r1] |= ctx.read(buf, np.uint32, nr * rw).reshape(nr, rw)
    return unpack_bits(words[None], p.width)[0]


def to_host(packed: PackedMasks, *, ctx: GpuContext | None = None) -> np.ndarray:
    """Download a packed stack: (N, H, row_words) uint32 (see :func:`unpack_bits`)."""
    if packed.words_host is not None:
        return packed.words_host.copy()
    ctx = ctx or get_context()
    out = np.zeros((packed.n, packed.height, packed.row_words), np.uint32)
    for c in packed.chunks:
        nk, nr = c.k1 - c.k0, c.r1 - c.r0
        out[c.k0 : c.k1, c.r0 : c.r1] = ctx.read(c.words, np.uint32, nk * nr * packed.row_words).reshape(nk, nr, -1)
    return out


def unpack_bits(packed: np.ndarray, width: int) -> np.ndarray:
    """Inverse of :func:`pack_bits`: (N, H, row_words) uint32 -> bool (N, H, width)."""
    n, h, rw = packed.shape
    bits = np.unpackbits(np.ascontiguousarray(packed).view(np.uint8).reshape(n, h, rw * 4), axis=2, bitorder="little")
    return bits[:, :, :width].astype(bool)
