"""Plain numpy reference for target lifting (tests only): the compositing of
:mod:`tests.render_oracle`, summing each Gaussian's weight ``alpha T`` inside and
outside a mask instead of colours."""
from __future__ import annotations

import numpy as np

from r360gpu.render.conventions import NEAR_PLANE

from render_oracle import composite, project


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
        for g, win, w, _, _ in composite(pr, camera, T):
            w_in[g] += float((w * m[win]).sum())
            w_out[g] += float((w * (1 - m[win])).sum())
    return w_in, w_out
