"""The render kernels' compute pipelines, with the conventions passed as WGSL ``override`` constants.

Every constant of :mod:`r360gpu.render.conventions` that a render shader needs
is an ``override`` without a default there, set here from
:data:`~r360gpu.render.conventions.SHADER_CONSTANTS`: a pipeline cannot be
built without them, so the shaders never hold a second copy.
"""
from __future__ import annotations

import math

from ..gpu.context import GpuContext
from ..gpu.shaders import shader_constant
from .conventions import SHADER_CONSTANTS, TILE

#: Threads per segment of workgroup_scan.wgsl's two-level scan, per shader: the square root of the
#: workgroup size (WG) each shader states.
SCAN_SEGMENTS = {name: math.isqrt(shader_constant(name, "WG")) for name in ("prefix_sum", "radix_sort", "radix_sort_blocks")}

if TILE != 16:  # render_rasterize.wgsl's workgroup shape covers 16 x 16 pixels
    raise ImportError(f"conventions.TILE must be 16 for render_rasterize.wgsl, got {TILE}")


def constants(name: str) -> dict:
    """The override constants pipeline ``name`` is built with."""
    c = dict(SHADER_CONSTANTS.get(name, {}))
    if name in SCAN_SEGMENTS:
        c["SCAN_SEG"] = SCAN_SEGMENTS[name]
    return c


def pipeline(ctx: GpuContext, name: str, entry_point: str = "main"):
    """The compute pipeline of render shader ``name`` with its constants."""
    return ctx.pipeline(name, entry_point, constants(name) or None)
