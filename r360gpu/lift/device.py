"""Host side of ``shaders/lift_accumulate.wgsl``: per-Gaussian compositing weight inside / outside a mask.

:class:`MaskLifter` runs :class:`LiftPass`, a
:class:`~r360gpu.render.tile_pass.TilePass`, through a
:class:`~r360gpu.render.Renderer` (:meth:`~r360gpu.render.Renderer.run_pass`):
projection, depth sort, binning and tile sort are the renderer's own, and the
pass composites with the rasteriser's rule (``shaders/composite.wgsl``), so a
Gaussian's weight at a pixel is exactly the ``alpha T`` the renderer blends it
with there.  The accumulators live on the device across views (64-bit fixed
point, see the shader); :meth:`MaskLifter.weights` reads them back once.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..gpu.context import BufferRange, GpuContext
from ..gpu.uniforms import uniform
from ..render.binning import TileLists
from ..render.conventions import COMPOSITE_CONSTANTS
from ..render.project import camera_arrays
from ..render.renderer import Renderer

#: Fixed-point units per unit of compositing weight (the shader's ``scale``): a tile's sum of at most
#: 256 pixel weights must fit 32 bits (256 x 2^20 = 2^28), and 2^-20 per thread and Gaussian is far
#: below any weight that matters (the renderer skips alphas under 1/255).
SCALE = float(1 << 20)

#: The WGSL names of lift_accumulate.wgsl's bindings, in the order the pass binds them.
BINDINGS = ("p", "ranges", "vals", "pos_op", "conic", "mask", "acc")


@dataclass(frozen=True)
class LiftPass:
    """The lifting kernel as a tile pass: adds each Gaussian's weight at the view's pixels, split by
    ``mask`` (H x W float32 shares), into ``acc`` (N x 4 u32, see :class:`MaskLifter`)."""

    mask: BufferRange
    acc: object

    def record(self, ctx: GpuContext, enc, lists: TileLists, cam: dict) -> None:
        window, proj = lists.window, lists.proj
        # row_base 0: run_pass records the whole image in one band
        params = uniform(ctx, "lift_accumulate", width=cam["width"], height=cam["height"], tiles_x=lists.tiles_x,
                         tile_begin=window.begin, num_tiles=window.end - window.begin, row_base=0, scale=SCALE)
        per_gaussian = max(16, lists.n * 16)
        ctx.dispatch(enc, ctx.pipeline("lift_accumulate", "main", COMPOSITE_CONSTANTS, bindings=BINDINGS),
                     [params, lists.ranges, ctx.span(lists.vals, 0, max(4, lists.num_keys * 4)),
                      BufferRange(proj.pos_op, 0, per_gaussian), BufferRange(proj.conic, 0, per_gaussian),
                      self.mask, BufferRange(self.acc, 0, per_gaussian)],
                     ctx.grid(window.end - window.begin))


@dataclass(frozen=True)
class _Together:
    """Several tile passes recorded over one view's tile lists (one projection and sort for all)."""

    passes: tuple

    def record(self, ctx: GpuContext, enc, lists: TileLists, cam: dict) -> None:
        for tile_pass in self.passes:
            tile_pass.record(ctx, enc, lists, cam)


class MaskLifter:
    """Accumulates, per Gaussian, its compositing weight inside and outside target masks.

    Parameters as `Renderer` (``background`` is
    irrelevant: weights do not depend on it).  Call `add_view` per
    (camera, mask), then `weights`.  ``acc`` is the device buffer of
    N x 4 u32: (in low, in high, out low, out high) words of the 64-bit
    fixed-point sums (`SCALE` units per unit weight); ``renderer`` the
    renderer whose tile lists the pass walks.  ``capture``: also sum each
    Gaussian's whole weight (a mask of ones) over the views added with
    ``capture=True``, into ``acc_capture`` (`capture_weights`), in the same
    pass as the view's mask: the integer sums a lifter of its own would make
    over those views with masks of ones, without projecting and sorting again.
    """

    def __init__(self, scene, *, capture: bool = False, **kwargs):
        self.renderer = Renderer(scene, **kwargs)
        self.ctx = self.renderer.ctx
        self.n = self.renderer.scene.n
        self.acc = self.ctx.buffer(max(16, self.n * 16), label="lift.acc")
        self.acc_capture = self.ctx.buffer(max(16, self.n * 16), label="lift.acc_capture") if capture else None
        self.views = 0

    def reset(self) -> None:
        """Zero the accumulators."""
        enc = self.ctx.encoder()
        enc.clear_buffer(self.acc, 0, self.acc.size)
        if self.acc_capture is not None:
            enc.clear_buffer(self.acc_capture, 0, self.acc_capture.size)
        self.ctx.submit(enc)
        self.views = 0

    def add_view(self, camera, mask, *, capture: bool = False) -> None:
        """Add the weights of one view (mask None: none to the masks' sums; with ``capture``, to the
        capture's only).

        mask: (H, W) array (bool, or float in [0, 1]: the pixel's share of
        target) at the camera's size, or a device buffer of H x W float32 in
        the same row-major order.  InputError on a wrong size or non-finite
        values (a device buffer is taken as is; values are clamped to [0, 1]).
        """
        cam = camera_arrays(camera)
        width, height = cam["width"], cam["height"]
        if width * height * 4 > self.ctx.max_binding_bytes:
            raise InputError(f"{cam['name']}: a {width}x{height} mask exceeds one "
                             f"{self.ctx.max_binding_bytes}-byte storage binding")
        passes = []
        if capture:
            if self.acc_capture is None:
                raise ValueError("MaskLifter: capture=True needs a lifter made with capture=True")
            ones = self.ctx.scratch("lift.ones", np.ones((height, width), np.float32))
            passes.append(LiftPass(BufferRange(ones, 0, max(4, width * height * 4)), self.acc_capture))
        if mask is not None:
            passes.insert(0, LiftPass(BufferRange(self._mask_buffer(cam, mask), 0, max(4, width * height * 4)),
                                      self.acc))
            self.views += 1
        if passes:
            self.renderer.run_pass(camera, passes[0] if len(passes) == 1 else _Together(tuple(passes)))

    def _mask_buffer(self, cam: dict, mask):
        """The device buffer of ``mask`` (see `add_view`) at ``cam``'s size."""
        width, height = cam["width"], cam["height"]
        if isinstance(mask, np.ndarray) or not hasattr(mask, "size"):
            m = np.asarray(mask)
            if m.shape != (height, width):
                raise InputError(f"{cam['name']}: mask is {m.shape[1] if m.ndim > 1 else '?'}x{m.shape[0]}"
                                 f" ({m.shape}), the camera is {width}x{height}")
            m = m.astype(np.float32)
            if not np.isfinite(m).all():
                raise InputError(f"{cam['name']}: mask has NaN or infinite values")
            return self.ctx.scratch("lift.mask", np.clip(m, 0.0, 1.0))
        if mask.size < width * height * 4:
            raise InputError(f"{cam['name']}: mask buffer holds {mask.size} bytes, "
                             f"a {width}x{height} float32 mask needs {width * height * 4}")
        return mask

    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """(w_in, w_out): (N,) float64 summed compositing weight inside / outside the masks."""
        return self._sums(self.acc)

    def capture_weights(self) -> np.ndarray:
        """(N,) float64 each Gaussian's whole compositing weight over the views added with ``capture``."""
        return self._sums(self.acc_capture)[0]

    def _sums(self, acc) -> tuple[np.ndarray, np.ndarray]:
        words = self.ctx.read(acc, np.uint32, 4 * self.n).reshape(-1, 4).astype(np.float64)
        w_in = (words[:, 0] + words[:, 1] * 4294967296.0) / SCALE
        w_out = (words[:, 2] + words[:, 3] * 4294967296.0) / SCALE
        return w_in, w_out

    def release(self) -> None:
        self.acc.destroy()
        if self.acc_capture is not None:
            self.acc_capture.destroy()
        self.renderer.release()
