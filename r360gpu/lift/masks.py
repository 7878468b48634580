"""Target masks for any pose: the lifted target rendered over the full scene.

Every Gaussian keeps its geometry and opacity; its colour becomes its label
(1 for target, 0 otherwise, on a black background), so the rendered red
channel at a pixel is the target's share of the pixel's composited weight,
``sum over target g of alpha_g T_g`` (what the background shows through,
``T``, counts as not target).  A pixel is target where that share is at
least :data:`MASK_SHARE`: the target is what the pixel mostly shows, and
anything in front of it (an occluder) or a half-transparent target takes the
share away exactly as it takes away the colour.  One render per view, the
renderer's own compositing.
"""
from __future__ import annotations

from typing import Iterable, Iterator

import numpy as np

from ..errors import InputError
from ..io.gaussians import Gaussians
from ..io.sh import C0 as SH_C0
from ..render.renderer import DeviceRender, Renderer

#: A pixel is target where the target holds at least this share of its composited weight.
MASK_SHARE = 0.5


def label_scene(scene: Gaussians, target: np.ndarray) -> Gaussians:
    """``scene``'s geometry with degree-0 colour 1 on ``target`` (N,) bool and 0 elsewhere."""
    target = np.asarray(target, bool)
    if target.shape != (scene.n,):
        raise InputError(f"target has {target.shape[0] if target.ndim else '?'} entries, the scene "
                         f"{scene.n} Gaussians")
    sh = np.empty((scene.n, 1, 3), np.float32)
    sh[:] = ((target.astype(np.float32) - 0.5) / np.float32(SH_C0))[:, None, None]
    return Gaussians(scene.means, scene.scales, scene.quats, scene.opacities, sh)


class TargetMaskRenderer:
    """Renders target masks of one scene and target at any camera (the scene uploaded once).

    scene: pre's `Gaussians` (N); target: (N,)
    bool (e.g. `LiftedTarget.target`); options: the render conventions.
    """

    def __init__(self, scene: Gaussians, target: np.ndarray, *, ctx=None, options=None):
        self.renderer = Renderer(label_scene(scene, target), ctx=ctx, options=options, background=(0.0, 0.0, 0.0))
        self.ctx = self.renderer.ctx

    def share(self, camera) -> np.ndarray:
        """(H, W) float32: the target's share of each pixel's composited weight, in [0, 1]."""
        return np.clip(self.renderer.render(camera).rgb[..., 0], 0.0, 1.0)

    def mask(self, camera) -> np.ndarray:
        """(H, W) bool target mask at ``camera``."""
        return self.share(camera) >= MASK_SHARE

    def device(self, camera) -> DeviceRender:
        """The labelled render left on the device: plane "r" (the first ``plane_stride`` float32s) is
        the target's share; threshold it at `MASK_SHARE`."""
        return self.renderer.render_device(camera)

    def release(self) -> None:
        self.renderer.release()


def target_masks(scene: Gaussians, target: np.ndarray, cameras: Iterable, *, ctx=None, options=None,
                 output: str = "numpy") -> Iterator:
    """Target masks of ``cameras`` (see the module docstring); yields one per camera.

    scene: pre's Gaussians (N); target: (N,) bool.  output "numpy": (H, W)
    bool; "device": a `DeviceRender` whose "r" plane
    holds the target's share (float32), on ``ctx``'s device.
    """
    if output not in ("numpy", "device"):
        raise InputError(f"output must be 'numpy' or 'device', got {output!r}")
    r = TargetMaskRenderer(scene, target, ctx=ctx, options=options)
    try:
        for cam in cameras:
            yield r.device(cam) if output == "device" else r.mask(cam)
    finally:
        r.release()
