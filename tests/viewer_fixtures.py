"""A tiny scene bundle for the viewer tests: a floor, two boxes and a target ball.

pre = floor + boxes + ball; method "clean" = pre without the ball; method
"floaters" = clean plus a cloud of junk where the ball was; reference = clean.
Cameras orbit the ball (z up); the target masks are the ball rendered alone
(alpha >= 0.5), so they match the renderer exactly.  Sizes are small so a
bundle takes well under a second on lavapipe.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from r360gpu.io import Camera, Gaussians, save_colmap, save_ply

C0 = 0.28209479177387814
BALL_CENTRE = np.array([0.0, 0.0, 0.35])
BALL_RADIUS = 0.3


def _gaussians(means, rgb, scale, opacity=0.95) -> Gaussians:
    n = len(means)
    sh = ((np.asarray(rgb, np.float64) - 0.5) / C0).reshape(n, 1, 3)
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return Gaussians(np.asarray(means, np.float64), np.full((n, 3), scale), quats, np.full(n, opacity), sh)


def _concat(parts) -> Gaussians:
    return Gaussians.concat(parts)


def make_parts(seed: int = 0, density: int = 24):
    """(background, ball, floaters) Gaussians."""
    rng = np.random.default_rng(seed)
    g = np.linspace(-1.5, 1.5, 2 * density)
    xx, yy = np.meshgrid(g, g)
    floor = np.stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)], 1)
    checker = ((np.floor(xx.ravel() * 2) + np.floor(yy.ravel() * 2)) % 2)[:, None]
    floor_rgb = 0.35 + 0.3 * checker * np.array([[1.0, 0.9, 0.7]])
    parts = [_gaussians(floor, floor_rgb, 1.6 / density, 0.99)]
    for centre, size, rgb in (((0.9, 0.6, 0.25), 0.25, (0.2, 0.5, 0.9)), ((-0.8, -0.7, 0.2), 0.2, (0.3, 0.8, 0.3))):
        p = rng.uniform(-size, size, (density * 20, 3)) + np.asarray(centre)
        parts.append(_gaussians(p, np.tile(rgb, (len(p), 1)), size / 6, 0.9))
    d = rng.normal(size=(density * 40, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ball = BALL_CENTRE + d * BALL_RADIUS * rng.uniform(0.6, 1.0, (len(d), 1))
    ball_rgb = np.tile((0.9, 0.2, 0.15), (len(ball), 1)) + rng.uniform(-0.05, 0.05, (len(ball), 3))
    ball_g = _gaussians(ball, np.clip(ball_rgb, 0, 1), BALL_RADIUS / 5, 0.95)
    junk = BALL_CENTRE + rng.uniform(-0.3, 0.3, (density * 8, 3))
    floaters = _gaussians(junk, rng.uniform(0.3, 0.9, (len(junk), 3)), 0.03, 0.8)
    return _concat(parts), ball_g, floaters


def orbit_cameras(n: int, width: int, height: int, radius: float = 2.6, height_z: float = 1.2) -> list[Camera]:
    cams = []
    for i in range(n):
        a = 2 * np.pi * i / n
        eye = np.array([radius * np.cos(a), radius * np.sin(a), height_z])
        f = BALL_CENTRE - eye
        f /= np.linalg.norm(f)
        down = -np.array([0.0, 0.0, 1.0]) - np.dot(-np.array([0.0, 0.0, 1.0]), f) * f
        down /= np.linalg.norm(down)
        right = np.cross(down, f)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([right, down, f], 1)
        c2w[:3, 3] = eye
        fy = height / (2 * np.tan(np.radians(25)))
        cams.append(Camera.from_camera_to_world(c2w, fy, fy, width / 2, height / 2, width, height, f"view_{i:02d}"))
    return cams


def write_bundle(root: Path, *, n_views: int = 6, width: int = 64, height: int = 48, ctx=None,
                 reference: bool = True, renders: bool = False) -> Path:
    """Write the bundle into ``root`` and return it.

    renders: add method "painted", the clean scene as a renders folder (rgb PNG + depth .npy per view).
    """
    from r360gpu.render import render

    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    bg, ball, junk = make_parts()
    pre = _concat([bg, ball])
    save_ply(root / "pre.ply", pre)
    save_ply(root / "clean.ply", bg)
    save_ply(root / "floaters.ply", _concat([bg, junk]))
    cams = orbit_cameras(n_views, width, height)
    save_colmap(root / "cameras", cams)
    (root / "masks").mkdir(exist_ok=True)
    for cam in cams:
        alpha = render(ball, cam, ctx=ctx).alpha
        assert cv2.imwrite(str(root / "masks" / f"{cam.name}.png"), ((alpha >= 0.5) * 255).astype(np.uint8))
    toml = ['name = "tiny"', 'prompt = "ball"', 'cameras = "cameras"', 'masks = "masks"', "",
            "[pre]", 'scene = "pre.ply"', ""]
    if reference:
        toml += ["[reference]", 'scene = "clean.ply"', ""]
    toml += ["[methods.clean]", 'scene = "clean.ply"', "", "[methods.floaters]", 'scene = "floaters.ply"', ""]
    if renders:
        for cam in cams:
            r = render(bg, cam, ctx=ctx)
            rgb8 = np.floor(np.clip(r.rgb, 0, 1) * 255 + 0.5).astype(np.uint8)
            (root / "painted" / "rgb").mkdir(parents=True, exist_ok=True)
            (root / "painted" / "depth").mkdir(parents=True, exist_ok=True)
            assert cv2.imwrite(str(root / "painted" / "rgb" / f"{cam.name}.png"), rgb8[..., ::-1])
            np.save(root / "painted" / "depth" / f"{cam.name}.npy", r.depth)
        toml += ["[methods.painted]", 'renders = "painted"', ""]
    (root / "scene.toml").write_text("\n".join(toml), encoding="utf-8")
    return root
