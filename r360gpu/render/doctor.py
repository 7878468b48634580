"""Self-checks of the renderer for ``r360gpu doctor`` (small, a few ms each).

Each check returns ``(ok, detail)``; expected values are computed here in
numpy from first principles, not by the renderer.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from ..gpu.context import GpuContext
from .renderer import Renderer
from .sort import host_argsort, sort_pairs

_SH_C0 = 0.28209479177387814


def _one_gaussian_scene(mean, scale: float, opacity: float, rgb):
    sh = ((np.asarray(rgb, np.float32) - 0.5) / _SH_C0).reshape(1, 1, 3)
    return SimpleNamespace(means=np.asarray([mean], np.float32), scales=np.full((1, 3), scale, np.float32),
                           quats=np.asarray([[1.0, 0, 0, 0]], np.float32),
                           opacities=np.asarray([opacity], np.float32), sh=sh)


def doctor_checks(ctx: GpuContext, rng: np.random.Generator) -> list:
    """``[(name, check)]`` for the doctor; ``check()`` returns ``(ok, detail)``."""

    def sort():
        keys = rng.integers(0, 5000, 100_003).astype(np.uint32)
        _, order = sort_pairs(ctx, keys)
        ok = np.array_equal(order, np.argsort(keys, kind="stable")) and np.array_equal(host_argsort(keys, 32), order)
        return ok, "100,003 keys with duplicates vs numpy stable argsort, and the host path (CPU adapters)"

    def one_gaussian():
        # An isotropic Gaussian on the optical axis at depth z: its footprint is
        # isotropic with variance (f s / z)^2 + 0.3 px^2, centred on pixel (32, 24).
        f, z, s, o, rgb = 40.0, 2.0, 0.1, 0.8, (0.2, 0.5, 0.9)
        cam = SimpleNamespace(R=np.eye(3), t=np.zeros(3), fx=f, fy=f, cx=32.5, cy=24.5, width=64, height=48,
                              name="doctor")
        renderer = Renderer(_one_gaussian_scene([0.0, 0.0, z], s, o, rgb), ctx=ctx)
        try:
            out = renderer.render(cam)
        finally:
            renderer.release()
        var = (f * s / z) ** 2 + 0.3
        dx = np.arange(64) - 32.0
        dy = np.arange(48)[:, None] - 24.0
        alpha = np.minimum(0.99, o * np.exp(-0.5 * (dx**2 + dy**2) / var))
        alpha = np.where(alpha >= 1 / 255, alpha, 0.0)
        covered = alpha >= 0.5
        ok = (np.allclose(out.alpha, alpha, atol=1e-5)
              and np.allclose(out.rgb, alpha[..., None] * np.asarray(rgb), atol=1e-5)
              and np.allclose(out.depth[covered], z, rtol=1e-5) and np.all(out.depth[~covered] == 0)
              and np.allclose(out.median_depth[covered], z, rtol=1e-5))
        return ok, "one Gaussian at 64x48: alpha, colour and depth vs closed form"

    return [("render: radix sort", sort), ("render: one Gaussian", one_gaussian)]
