"""Plain numpy reference for target lifting (tests only): the compositing of
:mod:`tests.render_oracle`, summing each Gaussian's weight ``alpha T`` inside and
outside a mask instead of colours."""
from __future__ import annotations

import numpy as np

from r360gpu.render.conventions import ALPHA_MAX, ALPHA_MIN, NEAR_PLANE, T_MIN, TILE

from render_oracle import project


def lift_weights(scene, cameras, masks, near: float = NEAR_PLANE):
    """(w_in, w_out) (N,) float64 for masks[i] (H, W) in [0, 1] at cameras[i]."""
    n = len(np.asarray(scene.means))
    w_in = np.zeros(n)
    w_out = np.zeros(n)
    for camera, mask in zip(cameras, masks):
        m = np.clip(np.asarray(mask, np.float64), 0, 1)
        pr = project(scene, camera, near)
        W, H = int(camera.width), int(camera.height)
        T = np.ones((H, W))
        done = np.zeros((H, W), bool)
        for g in np.argsort(pr["depth"], kind="stable"):
            if not pr["visible"][g]:
                continue
            x0, y0, x1, y1 = pr["rect"][g]
            xs = np.arange(x0 * TILE, min(x1 * TILE, W))
            ys = np.arange(y0 * TILE, min(y1 * TILE, H))
            if xs.size == 0 or ys.size == 0:
                continue
            win = (slice(ys[0], ys[-1] + 1), slice(xs[0], xs[-1] + 1))
            dx = pr["mean2d"][g, 0] - xs[None, :]
            dy = pr["mean2d"][g, 1] - ys[:, None]
            ca, cb, cc = pr["conic"][g]
            power = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
            alpha = np.minimum(ALPHA_MAX, pr["opacity"][g] * np.exp(power))
            use = (power <= 0) & (alpha >= ALPHA_MIN) & ~done[win]
            test_t = T[win] * (1 - alpha)
            stop = use & (test_t < T_MIN)
            done[win] |= stop
            blend = use & ~stop
            w = np.where(blend, alpha * T[win], 0.0)
            w_in[g] += float((w * m[win]).sum())
            w_out[g] += float((w * (1 - m[win])).sum())
            T[win] = np.where(blend, test_t, T[win])
    return w_in, w_out
