"""Plain numpy reference renderer for the WGSL 3DGS renderer (tests only).

Readable rather than fast: float64 throughout, Gaussians composited one at a
time in depth order over the pixels of their tile rectangle.  It implements
the conventions of :mod:`r360gpu.render.conventions` directly from INRIA's
formulas (3-sigma tile rectangle, no opacity-aware shortcut), so the GPU's
shortcuts are checked against it.
"""
from __future__ import annotations

import numpy as np

from r360gpu.io.sh import sh_to_color
from r360gpu.render.conventions import (
    AA_MIN_RATIO,
    ALPHA_MAX,
    ALPHA_MIN,
    COV2D_BLUR,
    FRUSTUM_GUARD,
    MEDIAN_T,
    NEAR_PLANE,
    NO_COVERAGE_ALPHA,
    SIGMA_EXTENT,
    T_MIN,
    TILE,
)


def quat_to_rotation(q: np.ndarray) -> np.ndarray:
    """(N, 4) (w, x, y, z) quaternions -> (N, 3, 3) rotation matrices."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], 1)


def project(scene, camera, near: float = NEAR_PLANE, antialiased: bool = False, principal_point: str = "camera") -> dict:
    """Per-Gaussian screen quantities (float64); ``visible`` marks the kept ones.

    antialiased: opacities times sqrt(max(AA_MIN_RATIO, det / det_blurred)),
    written from gsplat's ``add_blur`` (``gsplat/cuda/include/Utils.cuh``)
    and INRIA's ``h_convolution_scaling``.  principal_point "centre": the
    image centre instead of (cx, cy) (INRIA's original renderer).

    Returns dict with mean2d (N, 2) in pixel-index coordinates (pixel (x, y)
    centred at (x, y)), conic (N, 3), depth (N,), rgb (N, 3), opacity (N,),
    rect (N, 4) tiles [x0, x1) x [y0, y1) as (x0, y0, x1, y1), visible (N,).
    """
    R = np.asarray(camera.R, np.float64)
    t = np.asarray(camera.t, np.float64)
    W, H = int(camera.width), int(camera.height)
    fx, fy, cx, cy = float(camera.fx), float(camera.fy), float(camera.cx), float(camera.cy)
    if principal_point == "centre":
        cx, cy = W / 2.0, H / 2.0
    means = np.asarray(scene.means, np.float64)
    n = means.shape[0]
    p = means @ R.T + t
    z = p[:, 2]
    visible = z > near
    zs = np.where(visible, z, 1.0)

    rot = quat_to_rotation(np.asarray(scene.quats, np.float64))
    m = rot * np.asarray(scene.scales, np.float64)[:, None, :]  # M = R S (columns scaled)
    sigma = m @ np.transpose(m, (0, 2, 1))

    gx_, gy_ = FRUSTUM_GUARD * 0.5 * W / fx, FRUSTUM_GUARD * 0.5 * H / fy
    tx = np.clip(p[:, 0] / zs, -(cx / fx + gx_), (W - cx) / fx + gx_) * zs
    ty = np.clip(p[:, 1] / zs, -(cy / fy + gy_), (H - cy) / fy + gy_) * zs
    J = np.zeros((n, 2, 3))
    J[:, 0, 0] = fx / zs
    J[:, 0, 2] = -fx * tx / zs**2
    J[:, 1, 1] = fy / zs
    J[:, 1, 2] = -fy * ty / zs**2
    T = J @ R
    cov = T @ sigma @ np.transpose(T, (0, 2, 1))
    det_orig = cov[:, 0, 0] * cov[:, 1, 1] - cov[:, 0, 1] * cov[:, 1, 0]
    a = cov[:, 0, 0] + COV2D_BLUR
    b = cov[:, 0, 1]
    c = cov[:, 1, 1] + COV2D_BLUR
    det = a * c - b * b
    opacity = np.asarray(scene.opacities, np.float64)
    if antialiased:
        opacity = opacity * np.sqrt(np.maximum(AA_MIN_RATIO, det_orig / np.where(det > 0, det, 1.0)))
    visible &= det > 0
    det = np.where(det > 0, det, 1.0)
    conic = np.stack([c / det, -b / det, a / det], 1)
    mid = 0.5 * (a + c)
    lambda1 = mid + np.sqrt(np.maximum(0.1, mid * mid - det))
    radius = np.ceil(SIGMA_EXTENT * np.sqrt(lambda1))

    u = fx * p[:, 0] / zs + cx - 0.5
    v = fy * p[:, 1] / zs + cy - 0.5
    gx, gy = -(-W // TILE), -(-H // TILE)
    x0 = np.clip(np.floor((u - radius) / TILE), 0, gx)
    y0 = np.clip(np.floor((v - radius) / TILE), 0, gy)
    x1 = np.clip(np.floor((u + radius + TILE - 1) / TILE), 0, gx)
    y1 = np.clip(np.floor((v + radius + TILE - 1) / TILE), 0, gy)
    visible &= (x1 > x0) & (y1 > y0)

    centre = -R.T @ t
    rgb = sh_to_color(np.asarray(scene.sh, np.float64), means - centre) if n else np.zeros((0, 3))
    return dict(mean2d=np.stack([u, v], 1), conic=conic, depth=z, rgb=rgb, opacity=opacity,
                rect=np.stack([x0, y0, x1, y1], 1).astype(np.int64), visible=visible)


def composite(pr: dict, camera, T: np.ndarray, window=None):
    """Front-to-back compositing of projected Gaussians ``pr`` (:func:`project`) by the rasteriser's
    rules, one step per Gaussian in depth order: yields ``(g, win, w, blend, test_t)`` where ``win``
    is the Gaussian's pixel window (slices into ``T``), ``w = alpha T`` its compositing weight there
    (0 where it does not blend), ``blend`` where it blends and ``test_t`` the transmittance after it.
    ``T`` (H, W), the transmittance of ``window`` (x0, y0, width, height; default the whole image),
    is updated after each step."""
    x_lo, y_lo, W, H = window or (0, 0, int(camera.width), int(camera.height))
    done = np.zeros((H, W), bool)
    for g in np.argsort(pr["depth"], kind="stable"):
        if not pr["visible"][g]:
            continue
        x0, y0, x1, y1 = pr["rect"][g]
        xs = np.arange(max(x0 * TILE, x_lo), min(x1 * TILE, int(camera.width), x_lo + W))
        ys = np.arange(max(y0 * TILE, y_lo), min(y1 * TILE, int(camera.height), y_lo + H))
        if xs.size == 0 or ys.size == 0:
            continue
        win = (slice(ys[0] - y_lo, ys[-1] + 1 - y_lo), slice(xs[0] - x_lo, xs[-1] + 1 - x_lo))
        dx = pr["mean2d"][g, 0] - xs[None, :]
        dy = pr["mean2d"][g, 1] - ys[:, None]
        ca, cb, cc = pr["conic"][g]
        power = -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
        alpha = np.minimum(ALPHA_MAX, pr["opacity"][g] * np.exp(power))
        use = (power <= 0) & (alpha >= ALPHA_MIN) & ~done[win]
        t_old = T[win]
        test_t = t_old * (1 - alpha)
        stop = use & (test_t < T_MIN)
        done[win] |= stop
        blend = use & ~stop
        yield g, win, np.where(blend, alpha * t_old, 0.0), blend, test_t
        T[win] = np.where(blend, test_t, t_old)


def render(scene, camera, background=(0.0, 0.0, 0.0), near: float = NEAR_PLANE, window=None,
           antialiased: bool = False, no_coverage_alpha: float = NO_COVERAGE_ALPHA,
           principal_point: str = "camera") -> dict:
    """Reference images: rgb (H, W, 3), alpha, depth, median_depth (H, W), float64,
    and ``blended``: the number of pixel-Gaussian pairs composited.

    window: optional (x0, y0, width, height) pixel region of the camera's image
    to compute (the arrays then have that size); the default is the whole image.
    The other options are those of :class:`r360gpu.render.conventions.RenderOptions`.
    """
    pr = project(scene, camera, near, antialiased, principal_point)
    _, _, W, H = window or (0, 0, int(camera.width), int(camera.height))
    T = np.ones((H, W))
    color = np.zeros((H, W, 3))
    sum_w = np.zeros((H, W))
    sum_wz = np.zeros((H, W))
    median = np.zeros((H, W))
    median_found = np.zeros((H, W), bool)
    blended = 0
    for g, win, w, blend, test_t in composite(pr, camera, T, window):
        blended += int(blend.sum())
        color[win] += w[..., None] * pr["rgb"][g]
        sum_w[win] += w
        sum_wz[win] += w * pr["depth"][g]
        first = blend & ~median_found[win] & (test_t <= MEDIAN_T)
        median[win] = np.where(first, pr["depth"][g], median[win])
        median_found[win] |= first
    alpha_img = 1 - T
    covered = (alpha_img >= no_coverage_alpha) & (sum_w > 0)
    depth = np.where(covered, sum_wz / np.where(sum_w > 0, sum_w, 1), 0.0)
    return dict(rgb=color + T[..., None] * np.asarray(background, np.float64), alpha=alpha_img,
                depth=depth, median_depth=np.where(covered, median, 0.0), blended=blended)
