"""Viewer frame rate: frames per second of the viewer's full frame at 1280x720 (offscreen canvas).

A bundle of ``--n`` random Gaussians (pre; the method = pre without 10% of
them) is written to a temporary folder; the viewer then draws frames while
the camera orbits (every frame re-renders), at full resolution (no
progressive reduction: the number the goal ">= 30 frames/s at 1280x720
with 1 M Gaussians" refers to) and with the default progressive policy,
each with and without the |dD| + changed overlays, and with the panels.

    python bench/bench_viewer.py [--n 1000000] [--size 1280x720] [--frames 30]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import header  # noqa: E402


def write_bundle(root: Path, n: int, width: int, height: int) -> Path:
    import cv2

    from r360gpu.io import Camera, random_gaussians, save_colmap, save_ply

    g = random_gaussians(n, sh_degree=3, seed=0, extent=1.0)
    save_ply(root / "pre.ply", g)
    keep = np.random.default_rng(1).random(n) > 0.1
    save_ply(root / "method.ply", g.subset(np.flatnonzero(keep)))
    cams = []
    for i in range(8):
        a = 2 * np.pi * i / 8
        eye = np.array([3.0 * np.cos(a), 0.5, 3.0 * np.sin(a)])
        f = -eye / np.linalg.norm(eye)
        down = np.array([0.0, 1.0, 0.0]) - np.dot([0.0, 1.0, 0.0], f) * f
        down /= np.linalg.norm(down)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([np.cross(down, f), down, f], 1)
        c2w[:3, 3] = eye
        fy = height / (2 * np.tan(np.radians(30)))
        cams.append(Camera.from_camera_to_world(c2w, fy, fy, width / 2, height / 2, width, height, f"v{i}"))
    save_colmap(root / "cameras", cams)
    (root / "masks").mkdir()
    m = np.zeros((height, width), np.uint8)
    cv2.circle(m, (width // 2, height // 2), height // 4, 255, -1)
    for c in cams:
        cv2.imwrite(str(root / "masks" / f"{c.name}.png"), m)
    (root / "scene.toml").write_text('prompt = "thing"\ncameras = "cameras"\nmasks = "masks"\n[pre]\nscene = "pre.ply"\n'
                                     '[methods.method]\nscene = "method.ply"\n', encoding="utf-8")
    return root


def measure(app, canvas, frames: int) -> float:
    """Frames per second while orbiting (each frame a new camera)."""
    canvas.draw()
    t = time.perf_counter()
    for _ in range(frames):
        app.camera.orbit(3.0, 0.0)
        canvas.draw()
    return frames / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--size", default="1280x720")
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    header(f"viewer frames/s, {args.n} Gaussians, {width}x{height}")
    from rendercanvas.offscreen import OffscreenRenderCanvas

    from r360gpu.bundle import load_bundle
    from r360gpu.gpu import get_context
    from r360gpu.viewer.app import ViewerApp
    from r360gpu.viewer.quality import ResolutionPolicy

    ctx = get_context()
    with tempfile.TemporaryDirectory() as tmp:
        bundle = load_bundle(write_bundle(Path(tmp), args.n, width, height))
        for label, policy, keys, gui in (
            ("full resolution, method only", ResolutionPolicy(moving_scale=1.0), ("2",), False),
            ("full resolution, |dD| + changed overlays (renders pre too)", ResolutionPolicy(moving_scale=1.0),
             ("2", "x", "v"), False),
            ("full resolution, with panels", ResolutionPolicy(moving_scale=1.0), ("2",), True),
            ("progressive (default policy), method only", ResolutionPolicy(), ("2",), False),
        ):
            canvas = OffscreenRenderCanvas(size=(width, height))
            app = ViewerApp(bundle, canvas=canvas, ctx=ctx, policy=policy, gui=gui)
            canvas.request_draw(app.frame)
            for k in keys:
                app.key(k)
            fps = measure(app, canvas, args.frames)
            cam = app.last_camera
            print(f"{label:60s} {fps:7.1f} frames/s  (last render {cam.width}x{cam.height})")
            app.close()


if __name__ == "__main__":
    main()
