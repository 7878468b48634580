"""Tile binning: key windows, per-Gaussian tile counts, key emission, tile ranges.

Host side of ``shaders/render_bin.wgsl`` and ``shaders/render_ranges.wgsl``.

The duplicated key list (one key per Gaussian per touched tile) can exceed one
storage binding (a few million Gaussians at 4K), so the image's tiles are
processed in windows of consecutive tile ids whose keys fit one binding.  The
projection counts the tiles of each Gaussian's rectangle per tile row, an
upper bound of the keys (binning drops tiles the Gaussian cannot affect);
windows of whole rows are planned from those bounds, and each window's exact
key count is read back after counting.  A single row above a binding is split
in halves until every part fits (one tile holds at most N keys, and N x 16
bytes fits a binding).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..gpu.context import BufferRange, GpuContext
from ..gpu.shaders import workgroup_threads
from ..gpu.uniforms import uniform
from .shader_pipelines import pipeline
from .scan import exclusive_scan
from .scratch import Scratch

#: Invocations per workgroup of render_bin.wgsl's passes and render_ranges.wgsl (the shaders state them;
#: read once, not per recorded pass).
COUNT_WG = workgroup_threads("render_bin", "count")
EMIT_WG = workgroup_threads("render_bin", "emit")
RANGES_WG = workgroup_threads("render_ranges")
#: The WGSL names of the bindings of render_bin.wgsl (both passes) and render_ranges.wgsl, in binding order.
BIN_BINDINGS = ("p", "order", "rect", "counts", "keys", "vals", "pos_op", "conic")
RANGES_BINDINGS = ("p", "keys", "ranges")


@dataclass(frozen=True)
class TileWindow:
    """Tile ids [begin, end) and an upper bound of their key count (None: not known)."""

    begin: int
    end: int
    keys: int | None


@dataclass(frozen=True)
class TileLists:
    """One key window after the tile sort: what a per-tile pass over it reads.

    proj: the view's :class:`~r360gpu.render.project.Projected` Gaussians (n of them);
    ranges: (start, end) u32 key offsets per window tile; vals: u32 Gaussian index per
    key, front to back within each tile; num_keys: keys in the window; tiles_x: tiles
    per image row; window: the window's tile ids.
    """

    proj: object
    n: int
    ranges: BufferRange
    vals: object
    num_keys: int
    tiles_x: int
    window: TileWindow


def plan_windows(row_counts: np.ndarray, tiles_x: int, capacity: int) -> list[TileWindow]:
    """Group whole tile rows into windows of at most ``capacity`` keys.

    row_counts: (tiles_y,) key bounds per tile row (summed as Python ints).
    A row above ``capacity`` becomes its own window with an unknown count.
    """
    windows: list[TileWindow] = []
    begin_row, acc = 0, 0
    counts = [int(c) for c in row_counts]
    for row, c in enumerate(counts):
        if c > capacity:
            if row > begin_row:
                windows.append(TileWindow(begin_row * tiles_x, row * tiles_x, acc))
            windows.append(TileWindow(row * tiles_x, (row + 1) * tiles_x, None))
            begin_row, acc = row + 1, 0
        elif acc + c > capacity:
            windows.append(TileWindow(begin_row * tiles_x, row * tiles_x, acc))
            begin_row, acc = row, c
        else:
            acc += c
    if begin_row < len(counts):
        windows.append(TileWindow(begin_row * tiles_x, len(counts) * tiles_x, acc))
    return windows


def _per_gaussian(buf, n: int) -> BufferRange:
    return BufferRange(buf, 0, max(16, n * 16))


def record_counts(ctx: GpuContext, enc, proj, order, n: int, tiles_x: int, window: TileWindow,
                  scratch: Scratch) -> tuple[BufferRange, BufferRange]:
    """Record per-Gaussian key counts for ``window`` and their exclusive scan.

    ``proj`` is the :class:`~r360gpu.render.project.Projected` of the view.
    Returns (offsets window of n u32, 4-byte window holding the total).
    """
    counts = scratch.window("bin.counts", n * 4)
    params = uniform(ctx, "render_bin", n=n, tiles_x=tiles_x, tile_begin=window.begin, tile_end=window.end)
    ctx.dispatch(enc, pipeline(ctx, "render_bin", "count", BIN_BINDINGS),
                 [params, BufferRange(order, 0, counts.size), _per_gaussian(proj.rect, n), counts, None, None,
                  _per_gaussian(proj.pos_op, n), _per_gaussian(proj.conic, n)],
                 ctx.grid(-(-n // COUNT_WG)))
    total = exclusive_scan(ctx, enc, counts, n, scratch, "bin.scan")
    return counts, total


def record_emit(ctx: GpuContext, enc, proj, order, offsets: BufferRange, n: int, tiles_x: int,
                window: TileWindow, scratch: Scratch):
    """Record the emission of the window's ``window.keys`` (exact) keys; returns (keys, vals) buffers.

    The key lists are bound whole (``ctx.span``): their bind groups stay the same from frame to frame."""
    k = window.keys
    keys = scratch.get("bin.keys", k * 4)
    vals = scratch.get("bin.vals", k * 4)
    params = uniform(ctx, "render_bin", n=n, tiles_x=tiles_x, tile_begin=window.begin, tile_end=window.end)
    ctx.dispatch(enc, pipeline(ctx, "render_bin", "emit", BIN_BINDINGS),
                 [params, BufferRange(order, 0, offsets.size), _per_gaussian(proj.rect, n), offsets,
                  ctx.span(keys, 0, k * 4), ctx.span(vals, 0, k * 4),
                  _per_gaussian(proj.pos_op, n), _per_gaussian(proj.conic, n)],
                 ctx.grid(-(-n // EMIT_WG)))
    return keys, vals


def record_ranges(ctx: GpuContext, enc, keys, num_keys: int, num_tiles: int, scratch: Scratch) -> BufferRange:
    """Record the tile ranges of sorted window-local tile keys; returns (start, end) u32 pairs per tile."""
    ranges = scratch.window("bin.ranges", num_tiles * 8)
    enc.clear_buffer(ranges.buffer, 0, ranges.size)
    if num_keys > 0:
        ctx.dispatch(enc, pipeline(ctx, "render_ranges", "main", RANGES_BINDINGS),
                     [uniform(ctx, "render_ranges", n=num_keys), ctx.span(keys, 0, num_keys * 4), ranges],
                     ctx.grid(-(-num_keys // RANGES_WG)))
    return ranges
