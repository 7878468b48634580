"""The renderer's extension point: a pass over a view's depth-sorted tile lists.

The renderer projects a view's Gaussians, sorts them by depth, bins them into
16x16 tiles and sorts each tile's list front to back; then a *tile pass* walks
those lists.  The rasteriser (:class:`~r360gpu.render.rasterize.RasterPass`)
is one; target lifting (:mod:`r360gpu.lift.device`) another, which is why a
Gaussian's lifting weight at a pixel is exactly the ``alpha T`` the render
blends it with there.  :meth:`Renderer.run_pass <r360gpu.render.Renderer.run_pass>`
runs any pass over a view; the tile lists are the renderer's own.

A pass that composites as the renderer does includes ``shaders/composite.wgsl``
(the compositing rule, written once) and is built with
:data:`~r360gpu.render.conventions.COMPOSITE_CONSTANTS`.
"""
from __future__ import annotations

from typing import Protocol

from ..gpu.context import GpuContext
from .binning import TileLists


class TilePass(Protocol):
    """Records one compute pass over one key window's tile lists.

    ``record`` is called once per key window (a run of whole tile rows whose
    keys fit one storage binding; most views are one window), in window
    order, on the encoder the renderer submits next.  ``lists`` holds the
    window's tile ids, its ranges and Gaussian indices, and the view's
    projected Gaussians (:class:`~r360gpu.render.binning.TileLists`); ``cam``
    is the view's camera as the renderer projects it
    (:func:`~r360gpu.render.project.camera_arrays`, principal point applied):
    ``width``, ``height``, ``name``, intrinsics and pose.  The buffers in
    ``lists`` are the renderer's scratch: read them in the recorded pass,
    not after the next view.
    """

    def record(self, ctx: GpuContext, enc, lists: TileLists, cam: dict) -> None:
        ...
