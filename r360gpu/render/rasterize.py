"""Host side of ``shaders/render_rasterize.wgsl`` and the output image layout.

Output layout (one f32 buffer per view): six planes, each ``plane_stride``
floats (width * height rounded up to a multiple of 64 so every plane starts
256-byte aligned), row-major within a plane, in the order of :data:`PLANES`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gpu.context import BufferRange, GpuContext
from ..gpu.shaders import workgroup_threads
from ..gpu.uniforms import uniform
from .binning import TileLists
from .scratch import Scratch
from .shader_pipelines import pipeline

#: Plane order in the output buffer.
PLANES = ("r", "g", "b", "alpha", "depth", "median_depth")
#: Invocations per workgroup of render_interleave.wgsl (the shader states it).
INTERLEAVE_WG = workgroup_threads("render_interleave")
#: The WGSL names of render_rasterize.wgsl's bindings, in binding order (the output planes in PLANES order).
RASTERIZE_BINDINGS = ("p", "ranges", "vals", "pos_op", "conic", "rgb", "out_r", "out_g", "out_b", "out_alpha",
                      "out_depth", "out_median", "work")
#: The WGSL names of render_interleave.wgsl's bindings, in binding order.
INTERLEAVE_BINDINGS = ("p", "plane_r", "plane_g", "plane_b", "out")


def plane_stride(width: int, height: int) -> int:
    """Floats per output plane (width * height rounded up to a multiple of 64)."""
    return -(-(width * height) // 64) * 64


def plane_windows(image, stride: int) -> list[BufferRange]:
    """Binding windows of the six planes of ``image``."""
    return [BufferRange(image, i * stride * 4, stride * 4) for i in range(len(PLANES))]


@dataclass(frozen=True)
class Band:
    """Where a per-tile pass writes: ``image`` holds planes of ``stride`` floats whose first
    row is pixel row ``row_base`` of the view (0 unless the image is rendered in row bands)."""

    image: object
    stride: int
    row_base: int


@dataclass
class RasterPass:
    """The rasteriser as a :class:`~r360gpu.render.tile_pass.TilePass`: composites each window's
    tiles into ``band`` over ``background``; depth is 0 where alpha < ``min_alpha``.

    ``work`` is the window last recorded's work counters (see :func:`record_rasterize`), in
    ``scratch``'s buffer ``render.work``.
    """

    band: Band
    background: tuple
    min_alpha: float
    scratch: Scratch
    work: BufferRange | None = None

    def record(self, ctx: GpuContext, enc, lists: TileLists, cam: dict) -> None:
        self.work = self.scratch.window("render.work", (lists.window.end - lists.window.begin) * 8)
        record_rasterize(ctx, enc, lists, self.band, width=cam["width"], height=cam["height"],
                         background=self.background, min_alpha=self.min_alpha, work=self.work)


def record_rasterize(ctx: GpuContext, enc, lists: TileLists, band: Band, *, width: int, height: int, background,
                     min_alpha: float, work: BufferRange) -> None:
    """Record the rasterisation of the tiles of ``lists.window`` into ``band`` of a width x height view.

    ``work`` receives two u32 per tile of the window: pixel-Gaussian pairs
    evaluated and blended.
    """
    window = lists.window
    num_tiles = window.end - window.begin
    params = uniform(ctx, "render_rasterize", width=width, height=height, tiles_x=lists.tiles_x,
                     tile_begin=window.begin, num_tiles=num_tiles, bg_r=background[0], bg_g=background[1],
                     bg_b=background[2], min_alpha=min_alpha, row_base=band.row_base)
    per_gaussian = max(16, lists.n * 16)
    proj = lists.proj
    ctx.dispatch(
        enc, pipeline(ctx, "render_rasterize", "main", RASTERIZE_BINDINGS),
        [params, lists.ranges, ctx.span(lists.vals, 0, max(4, lists.num_keys * 4)),
         BufferRange(proj.pos_op, 0, per_gaussian), BufferRange(proj.conic, 0, per_gaussian),
         BufferRange(proj.rgb, 0, per_gaussian), *plane_windows(band.image, band.stride), work],
        ctx.grid(num_tiles),
    )


def planes_to_numpy(ctx: GpuContext, image, width: int, height: int, stride: int | None = None) -> dict[str, np.ndarray]:
    """Read the six planes of ``image`` (``stride`` floats apart; default: exactly
    sized) back as (height, width) float32 arrays."""
    stride = plane_stride(width, height) if stride is None else stride
    flat = ctx.read(image, np.float32, stride * len(PLANES)).reshape(len(PLANES), stride)[:, : width * height]
    return {name: flat[i].reshape(height, width) for i, name in enumerate(PLANES)}


def image_to_numpy(ctx: GpuContext, image, width: int, height: int, stride: int) -> dict[str, np.ndarray]:
    """The planes of a whole rendered image as numpy: "rgb" (height, width, 3) and
    "alpha", "depth", "median_depth" (height, width), all float32, bit for bit.

    On GPU adapters, when the interleaved colour fits one storage binding and one
    dispatch, the colour planes are interleaved on the device
    (``shaders/render_interleave.wgsl``) and read as they are, and the alpha, depth
    and median planes come back in a second read whose array they are: every value
    is copied once on the host.  Otherwise (and on CPU adapters, where the device is
    the same CPU: ``GpuContext.kernel_backend("render_interleave")``) one read of all
    six planes, the colour interleaved and the other planes copied out on the host.
    """
    pixels = width * height
    wg = INTERLEAVE_WG
    if (ctx.kernel_backend("render_interleave") == "cpu" or 3 * pixels * 4 > ctx.max_binding_bytes
            or pixels > wg * ctx.max_workgroups**2):
        p = planes_to_numpy(ctx, image, width, height, stride)
        return {"rgb": np.stack([p["r"], p["g"], p["b"]], axis=-1),
                **{k: p[k].copy() for k in ("alpha", "depth", "median_depth")}}
    first = PLANES.index("alpha")
    out = ctx.reusable("render.interleaved", 3 * pixels * 4)
    enc = ctx.encoder()
    ctx.dispatch(enc, pipeline(ctx, "render_interleave", "main", INTERLEAVE_BINDINGS),
                 [uniform(ctx, "render_interleave", n=pixels), *plane_windows(image, stride)[:first],
                  BufferRange(out, 0, 3 * pixels * 4)],
                 ctx.grid(-(-pixels // wg)))
    ctx.submit(enc)
    rgb = ctx.read(out, np.float32, 3 * pixels).reshape(height, width, 3)
    rest = ctx.read(image, np.float32, (len(PLANES) - first) * stride, offset=first * stride * 4)
    rest = rest.reshape(-1, stride)[:, :pixels]
    return {"rgb": rgb, **{name: rest[i - first].reshape(height, width)
                           for i, name in enumerate(PLANES) if i >= first}}
