"""A Gaussian scene uploaded to the device once and reused for every view."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..gpu.context import GpuContext

#: Floats per Gaussian in the packed parameter buffer:
#: (mx, my, mz, opacity), (sx, sy, sz, 0), (qw, qx, qy, qz).
PARAM_FLOATS = 12


def _array(scene, name: str, shape_tail: tuple, n: int | None) -> np.ndarray:
    try:
        arr = np.asarray(getattr(scene, name), dtype=np.float32)
    except AttributeError:
        raise InputError(f"scene has no '{name}' array (expected a Gaussians object)") from None
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != shape_tail:
        raise InputError(f"scene.{name} has shape {arr.shape}, expected (N, {', '.join(map(str, shape_tail))})")
    if n is not None and arr.shape[0] != n:
        raise InputError(f"scene.{name} has {arr.shape[0]} rows, scene.means has {n}")
    return arr


class DeviceScene:
    """The scene's parameters on the device.

    Attributes
    ----------
    n : int
        number of Gaussians N.
    sh_degree : int
        stored SH degree (0..3).
    params : wgpu buffer
        N x 12 float32 (see :data:`PARAM_FLOATS`).
    sh : wgpu buffer
        N x (3K) float32, the SH coefficients coefficient-major ((N, K, 3) flattened).
    """

    def __init__(self, ctx: GpuContext, scene):
        means = _array(scene, "means", (3,), None)
        n = int(means.shape[0])
        scales = _array(scene, "scales", (3,), n)
        quats = _array(scene, "quats", (4,), n)
        opacities = _array(scene, "opacities", (), n)
        sh = np.asarray(getattr(scene, "sh", None), dtype=np.float32)
        if sh.ndim != 3 or sh.shape[0] != n or sh.shape[2] != 3 or sh.shape[1] not in (1, 4, 9, 16):
            raise InputError(f"scene.sh has shape {sh.shape}, expected ({n}, K, 3) with K in 1, 4, 9, 16")
        packed = np.zeros((n, PARAM_FLOATS), np.float32)
        packed[:, 0:3] = means
        packed[:, 3] = opacities
        packed[:, 4:7] = scales
        packed[:, 8:12] = quats
        if not np.isfinite(packed).all() or not np.isfinite(sh).all():
            raise InputError("scene has NaN or infinite parameters")
        self.ctx = ctx
        self.n = n
        self.sh_degree = int(round(np.sqrt(sh.shape[1]))) - 1
        self.sh_stride = 3 * sh.shape[1]
        self.params = ctx.buffer(packed, label="scene.params")
        self.sh = ctx.buffer(np.ascontiguousarray(sh), label="scene.sh")

    def release(self) -> None:
        """Free the device buffers now."""
        self.params.destroy()
        self.sh.destroy()
