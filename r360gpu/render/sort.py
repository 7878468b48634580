"""Host side of the portable stable LSD radix sort: two shader variants, one permutation.

Sorts u32 keys with u32 values by their low bits.  Each pass is histogram ->
exclusive scan of the (digit, block) histogram -> stable scatter, all separate
dispatches: no subgroup operations, no decoupled look-back, nothing that needs
forward progress between workgroups.  Inputs larger than one storage binding
are processed in windows of one binding each (see the shaders' headers).

Variants (:data:`VARIANTS`, chosen per adapter by :func:`sort_variant`):

``serial`` (``shaders/radix_sort.wgsl``)
    4-bit digits; each thread walks 32 consecutive elements with its counters
    in registers.  Tuned for CPU implementations (lavapipe), where a thread is
    a SIMD lane and barriers are coroutine switches.
``blocks`` (``shaders/radix_sort_blocks.wgsl``)
    8-bit digits (half the passes); coalesced loads, each block sorted in
    workgroup memory, writes in runs of equal digits.  For GPUs.

Both sort by the same :func:`sorted_bits` low bits, stably, so they apply the
same permutation as :func:`host_argsort` (tests/test_render_sort.py).
"""
from __future__ import annotations

import math
import os

from ..gpu.context import BufferRange, GpuContext
from ..gpu.shaders import shader_constants
from ..gpu.uniforms import uniform
from .shader_pipelines import pipeline
from .scan import exclusive_scan
from .scratch import Scratch

_SIZES = shader_constants("radix_sort")  # the sizes radix_sort.wgsl states
#: Elements per workgroup of the serial variant (WG threads x ITEMS items).
BLOCK = _SIZES["BLOCK"]
#: Bits per pass, and buckets per digit, of the serial variant.
DIGIT_BITS = _SIZES["DIGIT_BITS"]
RADIX = _SIZES["RADIX"]
#: Shader of each variant.
VARIANTS = {"serial": "radix_sort", "blocks": "radix_sort_blocks"}
#: Environment variable that forces a variant (tests run both on lavapipe; benches compare them).
VARIANT_ENV = "R360GPU_RADIX_VARIANT"
#: The WGSL names of the bindings of both variants (radix_pass.wgsl, which each includes), in binding order.
SORT_BINDINGS = ("p", "keys_in", "vals_in", "keys_out", "vals_out", "hist")


def sort_variant(ctx: GpuContext) -> str:
    """The radix sort variant for ``ctx``'s adapter: "serial" on CPU adapters, else "blocks".

    ``R360GPU_RADIX_VARIANT`` (one of :data:`VARIANTS`) overrides.
    """
    forced = os.environ.get(VARIANT_ENV, "").strip()
    if forced:
        if forced not in VARIANTS:
            raise ValueError(f"{VARIANT_ENV}={forced!r}: expected one of {', '.join(VARIANTS)}")
        return forced
    return "serial" if ctx.adapter_info.get("adapter_type") == "CPU" else "blocks"


def sorted_bits(bits: int) -> int:
    """Low key bits that order a sort asked for ``bits`` bits: whole 4-bit digits, at most 32."""
    return min(32, 4 * math.ceil(max(0, bits) / 4))


# The sizes each variant's shader states (read once: recording a pass must not re-read the files).
_VARIANT_SIZES = {v: shader_constants(name) for v, name in VARIANTS.items()}


def _block(variant: str) -> int:
    return _VARIANT_SIZES[variant]["BLOCK"]


def window_elements(ctx: GpuContext, variant: str = "serial") -> int:
    """Elements per input/output window: one storage binding, and few enough
    blocks for one dispatch."""
    return min(ctx.max_binding_bytes // 4, _block(variant) * ctx.max_workgroups**2)


def radix_sort(ctx: GpuContext, enc, keys, vals, n: int, bits: int, scratch: Scratch, tag: str = "sort",
               variant: str | None = None):
    """Record a stable sort of the first ``n`` (key, value) u32 pairs by the low ``bits`` key bits.

    ``keys``/``vals`` are buffers of at least ``n`` u32 each; the low
    :func:`sorted_bits` bits of the keys take part (higher bits must be zero
    for a meaningful order, they are carried along).  Equal keys keep their
    input order.  ``variant``: one of :data:`VARIANTS` (default:
    :func:`sort_variant`); every variant gives the same result.  Returns
    ``(keys_sorted, vals_sorted)`` buffers: either the inputs (overwritten) or
    scratch buffers named after ``tag``; the inputs are clobbered in any case.
    Valid once ``enc`` has been submitted.
    """
    variant = variant or sort_variant(ctx)
    shader = VARIANTS[variant]
    sizes = _VARIANT_SIZES[variant]
    block, width, radix = sizes["BLOCK"], sizes["DIGIT_BITS"], sizes["RADIX"]
    kept = sorted_bits(bits)
    if n <= 1 or kept == 0:
        return keys, vals
    per = window_elements(ctx, variant)
    # Blocks are numbered across windows in input order, so the histogram
    # scan orders them like the input (windows need not hold whole blocks).
    windows = []
    total_blocks = 0
    for start in range(0, n, per):
        count = min(per, n - start)
        nb = -(-count // block)
        windows.append((start, count, total_blocks, nb))
        total_blocks += nb
    hist_bytes = radix * total_blocks * 4
    if hist_bytes > ctx.max_binding_bytes:
        raise ValueError(f"radix sort of {n} elements needs a {hist_bytes}-byte histogram binding")
    # Bindings of the whole scratch buffers where one window holds the input (ctx.span), so the tile
    # sort's bind groups stay the same while its key count changes from frame to frame.
    hist = ctx.span(scratch.get(f"{tag}.hist", hist_bytes), 0, hist_bytes)
    span = ctx.span if len(windows) == 1 else BufferRange
    src = (keys, vals)
    dst = (scratch.get(f"{tag}.keys", n * 4), scratch.get(f"{tag}.vals", n * 4))
    pipe_hist = pipeline(ctx, shader, "histogram", SORT_BINDINGS)
    pipe_scatter = pipeline(ctx, shader, "scatter", SORT_BINDINGS)
    for shift in range(0, kept, width):
        # The blocks variant's last digit may be narrower (e.g. 12 bits = 8 + 4).
        digit = {"digit_bits": min(width, kept - shift)}
        for start, count, block_base, nb in windows:
            params = uniform(ctx, shader, n=count, shift=shift, block_base=block_base, total_blocks=total_blocks,
                             out_base=0, out_count=0, num_blocks=nb, **digit)
            ctx.dispatch(
                enc, pipe_hist,
                [params, span(src[0], start * 4, count * 4), None, None, None, hist],
                ctx.grid(nb),
            )
        exclusive_scan(ctx, enc, hist, radix * total_blocks, scratch, f"{tag}.hscan")
        for start, count, block_base, nb in windows:
            for out_start, out_count, _, _ in windows:
                params = uniform(ctx, shader, n=count, shift=shift, block_base=block_base,
                                 total_blocks=total_blocks, out_base=out_start, out_count=out_count, num_blocks=nb,
                                 **digit)
                ctx.dispatch(
                    enc, pipe_scatter,
                    [
                        params,
                        span(src[0], start * 4, count * 4),
                        span(src[1], start * 4, count * 4),
                        span(dst[0], out_start * 4, out_count * 4),
                        span(dst[1], out_start * 4, out_count * 4),
                        hist,
                    ],
                    ctx.grid(nb),
                )
        src, dst = dst, src
    return src


def host_argsort(keys, bits: int):
    """The permutation :func:`radix_sort` applies to ``keys`` (host uint32 array), computed in numpy.

    :func:`radix_sort` (either variant) is a stable sort by the low
    :func:`sorted_bits` key bits, ``4 * ceil(bits / 4)``; so is this (numpy's
    stable sort, a radix sort for keys of 16 bits or fewer).  The renderer
    takes this path on CPU adapters, where one host sort costs less CPU than
    the shader's passes (:meth:`GpuContext.kernel_backend` "sort"); the
    results are identical (tests/test_render_sort.py, tests/test_render_pipeline.py).
    """
    import numpy as np

    keys = np.asarray(keys, dtype=np.uint32)
    kept = sorted_bits(bits)
    if kept <= 0 or keys.size <= 1:
        return np.arange(keys.size, dtype=np.intp)
    if kept < 32:
        keys = keys & np.uint32((1 << kept) - 1)
    # LSD in 16-bit halves: numpy's stable sort is a radix sort for uint16 keys, a merge sort for uint32
    perm = np.argsort((keys & np.uint32(0xFFFF)).astype(np.uint16), kind="stable")
    if kept > 16:
        perm = perm[np.argsort((keys[perm] >> np.uint32(16)).astype(np.uint16), kind="stable")]
    return perm


def host_sort(ctx: GpuContext, keys, vals, n: int, bits: int):
    """:func:`radix_sort` of the first ``n`` (key, value) pairs of two device buffers, done in
    numpy (:func:`host_argsort`): the pairs are read back, sorted and written back in place.
    Returns ``(keys, vals)``, the same buffers.  Waits for the device (every command
    submitted before it must be finished), so it is for CPU adapters, where waiting is cheap."""
    import numpy as np

    if n > 1 and bits > 0:
        host_keys, host_vals = ctx.read(keys, np.uint32, n), ctx.read(vals, np.uint32, n)
        perm = host_argsort(host_keys, bits)
        ctx.write(keys, host_keys[perm])
        ctx.write(vals, host_vals[perm])
    return keys, vals


def sort_pairs(ctx: GpuContext, keys, vals=None, bits: int = 32, scratch: Scratch | None = None,
               variant: str | None = None):
    """Sort host arrays on the device (convenience wrapper for tests and callers).

    keys: (n,) uint32; vals: (n,) uint32 or None (then ``arange(n)``).
    Returns ``(sorted_keys, sorted_vals)`` numpy uint32 arrays, stable by the
    low ``bits`` bits of the keys.  ``variant``: as :func:`radix_sort`.
    """
    import numpy as np

    keys = np.ascontiguousarray(keys, dtype=np.uint32)
    n = int(keys.shape[0])
    vals = np.arange(n, dtype=np.uint32) if vals is None else np.ascontiguousarray(vals, dtype=np.uint32)
    if vals.shape != keys.shape:
        raise ValueError(f"keys {keys.shape} and values {vals.shape} differ in shape")
    if n == 0:
        return keys.copy(), vals.copy()
    scratch = scratch or Scratch(ctx)
    kb, vb = ctx.buffer(keys), ctx.buffer(vals)
    enc = ctx.encoder()
    ks, vs = radix_sort(ctx, enc, kb, vb, n, bits, scratch, variant=variant)
    ctx.submit(enc)
    return ctx.read(ks, np.uint32, n), ctx.read(vs, np.uint32, n)
