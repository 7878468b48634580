"""3DGS renderer in WGSL: project -> depth sort -> bin -> tile sort -> tile ranges -> rasterise.

Conventions (pixel centres, near plane, compositing constants, the
no-coverage rule for depth) are defined in :mod:`r360gpu.render.conventions`;
the stages live in one module each (:mod:`.project`, :mod:`.sort`,
:mod:`.scan`, :mod:`.binning`, :mod:`.rasterize`) with one WGSL file each
under ``shaders/``.

Public API::

    render(scene, camera, *, ctx=None, background=(0, 0, 0), output="numpy", near=NEAR_PLANE,
           antialiased=False, no_coverage_alpha=NO_COVERAGE_ALPHA, principal_point="camera")
        -> Render(rgb (H, W, 3), depth (H, W), median_depth (H, W), alpha (H, W))   float32
        or DeviceRender (output="device": six f32 planes in one wgpu buffer, see DeviceRender)
    render_views(scene, cameras, *, ..., progress=False) -> iterator of the same, one per camera
    Renderer(scene, ...)  keeps the scene on the device; .render(camera) (images beyond one device
        buffer in row bands), .render_device(camera), .run_pass(camera, tile_pass)
    TilePass             the extension point: a pass over a view's depth-sorted tile lists
        (.record(ctx, enc, lists, cam) per key window; r360gpu.render.tile_pass)
    RenderOptions        the conventions above as one object (r360gpu.render.conventions)
    doctor_checks(ctx, rng) -> [(name, check)]   self-checks for ``r360gpu doctor``
"""
from __future__ import annotations

from .conventions import NEAR_PLANE, NO_COVERAGE_ALPHA, RenderOptions
from .doctor import doctor_checks
from .renderer import DeviceRender, Render, Renderer, RenderStats, render, render_views
from .rasterize import PLANES
from .tile_pass import TilePass

__all__ = [
    "NEAR_PLANE",
    "NO_COVERAGE_ALPHA",
    "PLANES",
    "DeviceRender",
    "Render",
    "RenderOptions",
    "RenderStats",
    "TilePass",
    "doctor_checks",
    "Renderer",
    "render",
    "render_views",
]
