"""Small scene bundles on disk for the bundle, renders and ``check`` tests.

Everything is written with r360gpu's own writers (splats, cameras) and
OpenCV (masks, renderings); sizes are tiny so a bundle takes milliseconds.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from r360gpu.io import Camera, Gaussians, random_gaussians, save_colmap, save_ply, save_splat

W, H = 16, 12
VIEWS = ("view_00", "view_01", "view_02")


def camera(name: str, width: int = W, height: int = H, z: float = 3.0) -> Camera:
    return Camera(np.eye(3), [0.0, 0.0, z], 20.0, 20.0, width / 2, height / 2, width, height, name)


def mask_image(width: int = W, height: int = H) -> np.ndarray:
    m = np.zeros((height, width), np.uint8)
    m[height // 4: height // 2, width // 4: width // 2] = 255
    return m


def target_object(z: float = 3.0) -> Gaussians:
    """The object the masks mark, as pre holds it: one opaque Gaussian per mask pixel, at depth
    ``z`` in front of :func:`camera` (the frame check refuses a pre that does not cover its target)."""
    rows, cols = np.nonzero(mask_image())
    px = z / 20.0  # one pixel at depth z, for camera()'s focal length
    means = np.stack([(cols + 0.5 - W / 2) * px, (rows + 0.5 - H / 2) * px, np.zeros(rows.size)], axis=1)
    n = len(means)
    sh = np.zeros((n, 4, 3))
    sh[:, 0] = 0.5
    return Gaussians(means, np.full((n, 3), 0.6 * px), np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.full(n, 0.99), sh)


def write_mask(path: Path, width: int = W, height: int = H) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), mask_image(width, height))
    return path


def write_rgb(path: Path, width: int = W, height: int = H, seed: int = 0) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)
    assert cv2.imwrite(str(path), img)
    return path


def write_depth_png16(path: Path, width: int = W, height: int = H, seed: int = 0) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    d = np.random.default_rng(seed).integers(500, 5000, (height, width), dtype=np.uint16)
    assert cv2.imwrite(str(path), d)
    return path


def write_renders(folder: Path, views=VIEWS, width: int = W, height: int = H, depth: bool = True) -> Path:
    for i, v in enumerate(views):
        write_rgb(folder / "rgb" / f"{v}.png", width, height, seed=i)
        if depth:
            write_depth_png16(folder / "depth" / f"{v}.png", width, height, seed=i)
    return folder


SCENE_TOML = """\
name = "room"
prompt = "sofa"
cameras = "cameras"
masks = "masks"

[pre]
scene = "pre.ply"

[reference]
scene = "ref.splat"

[methods.clean]
scene = "methods/clean.ply"

[methods.objectclear]
renders = "methods/objectclear"
depth_scale = 0.001

[options]
background = [1.0, 1.0, 1.0]
depth = "median"
"""


def make_bundle(root: Path, toml: str = SCENE_TOML, views=VIEWS) -> Path:
    """A valid bundle in ``root``: 3 views (COLMAP cameras named ``<view>.jpg``), masks, a
    pre .ply, a reference .splat, one splat method and one renders method."""
    root.mkdir(parents=True, exist_ok=True)
    save_colmap(root / "cameras", [camera(f"{v}.jpg") for v in views])
    for v in views:
        write_mask(root / "masks" / f"{v}.png")
    save_ply(root / "pre.ply", Gaussians.concat([random_gaussians(40, sh_degree=1, seed=1), target_object()]))
    save_splat(root / "ref.splat", random_gaussians(30, sh_degree=0, seed=2))
    (root / "methods").mkdir(exist_ok=True)
    save_ply(root / "methods" / "clean.ply", random_gaussians(35, sh_degree=1, seed=3))
    write_renders(root / "methods" / "objectclear", views)
    (root / "scene.toml").write_text(toml, encoding="utf-8")
    return root


def make_remove360(root: Path, views=VIEWS, prompt: str | None = "table") -> Path:
    """A folder in the public Remove360 evaluation layout (8-bit depth PNGs, as the public code writes)."""
    for i, v in enumerate(views):
        write_rgb(root / "rgb" / "before" / f"{v}.png", seed=i)
        write_rgb(root / "rgb" / "after" / f"{v}.jpg", seed=10 + i)
        for which, offset in (("before", 0), ("after", 20)):
            d = np.full((H, W), 100 + offset, np.uint8)
            (root / "depth" / which).mkdir(parents=True, exist_ok=True)
            assert cv2.imwrite(str(root / "depth" / which / f"{v}.png"), d)
        write_mask(root / "masks" / f"{v}.png")
        write_rgb(root / "images" / "before" / f"{v}.jpg", seed=30 + i)
        write_rgb(root / "images" / "after" / f"other_{i}.jpg", seed=40 + i)
    # The public pipeline stores SAM segments of images/before beside the masks.
    (root / "masks" / f"{views[0]}.json").write_text("[]")
    if prompt is not None:
        (root / "prompt.txt").write_text(prompt + "\n")
    return root
