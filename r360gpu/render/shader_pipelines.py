"""The render kernels' compute pipelines, with the conventions passed as WGSL ``override`` constants
and the bindings checked by name.

Every constant of :mod:`r360gpu.render.conventions` that a render shader needs
is an ``override`` without a default there, set here from
:data:`~r360gpu.render.conventions.SHADER_CONSTANTS`: a pipeline cannot be
built without them, so the shaders never hold a second copy.

Every pipeline is made with the WGSL names of the resources its dispatches
bind, by position (each host module states them beside its dispatches, as
``*_BINDINGS``); a shader that declares other names there is refused when the
pipeline is made (:func:`r360gpu.gpu.shaders.check_bindings`), with a message
naming the shader and the binding, instead of rendering a wrong image.
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


def pipeline(ctx: GpuContext, name: str, entry_point: str, bindings: tuple):
    """The compute pipeline of ``entry_point`` of render shader ``name`` with its constants; ``bindings``
    the WGSL variable bound at each ``@binding`` position (ValueError when the shader disagrees)."""
    return ctx.pipeline(name, entry_point, constants(name) or None, bindings=bindings)
