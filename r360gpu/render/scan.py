"""Host side of ``shaders/prefix_sum.wgsl``: exclusive prefix sum of u32 arrays.

A multi-level reduce-then-scan: level 0 scans blocks of :data:`BLOCK` elements
and writes one total per block; the block totals are scanned recursively and
added back.  Each level is its own dispatch, so no workgroup ever waits for
another (portable to software Vulkan, which has no forward-progress guarantee).
"""
from __future__ import annotations

from ..gpu.context import BufferRange, GpuContext
from ..gpu.shaders import shader_constant
from ..gpu.uniforms import uniform
from .shader_pipelines import pipeline
from .scratch import Scratch

#: Elements scanned by one workgroup (WG threads x ITEMS items), as prefix_sum.wgsl states it.
BLOCK = shader_constant("prefix_sum", "BLOCK")
#: The WGSL names of prefix_sum.wgsl's bindings (both passes), in binding order.
SCAN_BINDINGS = ("p", "data", "block_sums")


def exclusive_scan(ctx: GpuContext, enc, data, n: int, scratch: Scratch, tag: str = "scan") -> BufferRange:
    """Record an in-place exclusive scan of ``n`` u32 values of ``data`` on ``enc``.

    ``data`` is a buffer or :class:`BufferRange` whose first ``n`` u32 are
    scanned; it must fit one storage binding.  Returns a 4-byte window holding
    the grand total (valid once ``enc`` has been submitted).  Sums wrap modulo
    2**32; callers keep totals below that.
    """
    # whole scratch buffers bound (ctx.span): the bind groups stay the same while n changes
    if isinstance(data, BufferRange):
        window = ctx.span(data.buffer, data.offset, max(4, n * 4))
    else:
        window = ctx.span(data, 0, max(4, n * 4))
    if n * 4 > ctx.max_binding_bytes or n > BLOCK * ctx.max_workgroups**2:
        raise ValueError(f"scan of {n} elements exceeds one storage binding ({ctx.max_binding_bytes} bytes) "
                         "or one dispatch")
    level = 0
    pending = []
    while True:
        num_blocks = max(1, -(-n // BLOCK))
        sums = ctx.span(scratch.get(f"{tag}.L{level}", num_blocks * 4), 0, num_blocks * 4)
        params = uniform(ctx, "prefix_sum", n=n, num_blocks=num_blocks)
        if n > 0:
            ctx.dispatch(enc, pipeline(ctx, "prefix_sum", "scan_blocks", SCAN_BINDINGS), [params, window, sums], ctx.grid(num_blocks))
        else:
            enc.clear_buffer(sums.buffer, 0, 4)
        if num_blocks == 1:
            total = BufferRange(sums.buffer, 0, 4)
            break
        pending.append((window, sums, params, num_blocks))
        window, n, level = sums, num_blocks, level + 1
    for window, sums, params, num_blocks in reversed(pending):
        ctx.dispatch(enc, pipeline(ctx, "prefix_sum", "add_block_sums", SCAN_BINDINGS), [params, window, sums], ctx.grid(num_blocks))
    return total
