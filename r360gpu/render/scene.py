"""A Gaussian scene uploaded to the device once and reused for every view."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..gpu.context import GpuContext

#: Floats per Gaussian in the packed parameter buffer:
#: (mx, my, mz, opacity), (sx, sy, sz, 0), (qw, qx, qy, qz).
PARAM_FLOATS = 12


def storage_origin(means) -> np.ndarray:
    """(3,) float64: the point the device stores the centres relative to.

    The projection computes a centre's camera coordinates ``R x + t`` in float32.  A scene far
    from its coordinates' origin (a trainer's frame with a large shift, a georeferenced capture)
    has ``x`` and ``t`` both large, and their sum loses the digits that place the Gaussian in the
    image: 100 scene radii away, the same file gives another lifted set than the scene around its
    origin (bench/frame_invariance_sweep.py).  So such a scene is stored relative to the centre of
    its bounding box, subtracted in float64, and the camera moved to match (`project`).  A scene
    whose box centre lies within the box's half-diagonal of the origin is stored as it is: the
    same float32 numbers as the file's, bit for bit.
    """
    m = np.asarray(means, np.float64).reshape(-1, 3)
    m = m[np.isfinite(m).all(axis=1)]
    if not len(m):
        return np.zeros(3)
    lo, hi = m.min(axis=0), m.max(axis=0)
    centre = (lo + hi) / 2
    return centre if np.linalg.norm(centre) > np.linalg.norm(hi - lo) / 2 else np.zeros(3)


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
    origin : (3,) float64
        the centres are stored relative to it (`storage_origin`).
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
        self.origin = storage_origin(scene.means)
        packed[:, 0:3] = np.asarray(scene.means, np.float64) - self.origin if self.origin.any() else means
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
