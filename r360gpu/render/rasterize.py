"""Host side of ``shaders/render_rasterize.wgsl`` and the output image layout.

Output layout (one f32 buffer per view): six planes, each ``plane_stride``
floats (width * height rounded up to a multiple of 64 so every plane starts
256-byte aligned), row-major within a plane, in the order of :data:`PLANES`.
"""
from __future__ import annotations

import numpy as np

from ..gpu.context import BufferRange, GpuContext
from ..gpu.uniforms import uniform
from .shader_pipelines import pipeline

#: Plane order in the output buffer.
PLANES = ("r", "g", "b", "alpha", "depth", "median_depth")


def plane_stride(width: int, height: int) -> int:
    """Floats per output plane (width * height rounded up to a multiple of 64)."""
    return -(-(width * height) // 64) * 64


def plane_windows(image, stride: int) -> list[BufferRange]:
    """Binding windows of the six planes of ``image``."""
    return [BufferRange(image, i * stride * 4, stride * 4) for i in range(len(PLANES))]


def record_rasterize(ctx: GpuContext, enc, *, ranges: BufferRange, vals, num_keys: int, pos_op, conic, rgb,
                     n: int, image, stride: int, row_base: int, width: int, height: int, tiles_x: int,
                     tile_begin: int, num_tiles: int, background, min_alpha: float, work: BufferRange) -> None:
    """Record the rasterisation of tiles [tile_begin, tile_begin + num_tiles) into ``image``.

    ``image`` holds six planes of ``stride`` floats whose first row is pixel
    row ``row_base`` of the width x height view (0 unless rendering in row
    bands).  ``work`` receives two u32 per tile of the window: pixel-Gaussian
    pairs evaluated and blended.
    """
    params = uniform(ctx, "render_rasterize", width=width, height=height, tiles_x=tiles_x, tile_begin=tile_begin,
                     num_tiles=num_tiles, bg_r=background[0], bg_g=background[1], bg_b=background[2],
                     min_alpha=min_alpha, row_base=row_base)
    per_gaussian = max(16, n * 16)
    ctx.dispatch(
        enc, pipeline(ctx, "render_rasterize"),
        [params, ranges, BufferRange(vals, 0, max(4, num_keys * 4)),
         BufferRange(pos_op, 0, per_gaussian), BufferRange(conic, 0, per_gaussian), BufferRange(rgb, 0, per_gaussian),
         *plane_windows(image, stride), work],
        ctx.grid(num_tiles),
    )


def planes_to_numpy(ctx: GpuContext, image, width: int, height: int, stride: int | None = None) -> dict[str, np.ndarray]:
    """Read the six planes of ``image`` (``stride`` floats apart; default: exactly
    sized) back as (height, width) float32 arrays."""
    stride = plane_stride(width, height) if stride is None else stride
    flat = ctx.read(image, np.float32, stride * len(PLANES)).reshape(len(PLANES), stride)[:, : width * height]
    return {name: flat[i].reshape(height, width) for i, name in enumerate(PLANES)}
