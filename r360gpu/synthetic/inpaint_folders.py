"""Generated folders in the layouts of the inpainting benchmarks (360-USID, SPIn-NeRF).

`write_inpaint_example` writes, from a seed, procedural "photographs" of scenes without
the object, object masks with anti-aliased edges (so mask values between 0 and 255 occur, as in
real rendered masks) and the renders of two simulated inpainting methods: ``blur`` fills the
object's region with a blurred copy of the background (a plausible inpainting), ``flat`` with
the photograph's mean colour (a poor one); both add a little noise, as a render never equals
a photograph.  Camera motion is a shifting crop of a larger picture per scene.  Layout::

    OUT/360usid/data/SCENE/test_images/IMG_<i>.jpg              photographs (JPEG, unpadded numbers)
    OUT/360usid/output/SCENE/test/ours_30000/object_mask/<i>.png the object masks (as the script's fixed folder)
    OUT/360usid/output/SCENE/test/METHOD/renders/<i>.png         a method's renders (object_mask/ beside them)
    OUT/spinnerf/data/SCENE/images/IMG_<i>.jpg                  N test photographs, then training ones with the object
    OUT/spinnerf/data/SCENE/images/label/IMG_<i>.png            object masks of every photograph (0/1, as released)
    OUT/spinnerf/output/SCENE/METHOD/renders/<i>.png             a method's renders of the test views

The folder is written beside its final place and renamed into it; an earlier example folder (it
holds `MARKER`) is replaced, any other existing non-empty folder refused.
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError

MARKER = "r360-inpaint-example.json"
METHODS = ("blur", "flat")
SCENES = ("carton", "cone", "cookie", "newcone", "plant", "skateboard", "sunflower")


def _background(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A smooth colour field with some texture, (h, w, 3) float32 in [0, 1]."""
    coarse = rng.uniform(0.15, 0.85, size=(max(2, h // 48), max(2, w // 48), 3)).astype(np.float32)
    field = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
    fine = cv2.resize(rng.normal(0.0, 0.06, size=(max(2, h // 4), max(2, w // 4), 3)).astype(np.float32), (w, h),
                      interpolation=cv2.INTER_LINEAR)
    return np.clip(field + fine, 0.0, 1.0)


def _mask(h: int, w: int, centre: tuple[float, float], axes: tuple[float, float]) -> np.ndarray:
    """uint8 (h, w) ellipse, 255 inside, anti-aliased edge."""
    m = np.zeros((h, w), np.uint8)
    shift = 4  # sub-pixel centre: fractional edges everywhere
    c = (int(round(centre[0] * (1 << shift))), int(round(centre[1] * (1 << shift))))
    a = (int(round(axes[0] * (1 << shift))), int(round(axes[1] * (1 << shift))))
    cv2.ellipse(m, c, a, 0.0, 0.0, 360.0, 255, -1, cv2.LINE_AA, shift)
    return m


def _views(rng: np.random.Generator, n: int, h: int, w: int):
    """Per view: the photograph (no object), the object mask, and the object's colour."""
    big = _background(rng, h + h // 2, w + w // 2)
    colour = rng.uniform(0.0, 1.0, size=3).astype(np.float32)
    for i in range(n):
        t = i / max(1, n - 1)
        y0, x0 = int(round(t * (h // 2))), int(round((1 - t) * (w // 2)))
        photo = big[y0:y0 + h, x0:x0 + w]
        centre = (w * (0.35 + 0.3 * t) + rng.uniform(-2, 2), h * 0.5 + rng.uniform(-2, 2))
        yield photo, _mask(h, w, centre, (w * 0.14, h * 0.2)), colour


def _render(method: str, photo: np.ndarray, mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    inside = (mask.astype(np.float32) / 255.0)[:, :, None]
    if method == "blur":
        fill = cv2.GaussianBlur(photo, (0, 0), sigmaX=max(2.0, photo.shape[1] / 40))
    else:
        fill = np.broadcast_to(photo.reshape(-1, 3).mean(axis=0), photo.shape)
    out = photo * (1 - inside) + fill * inside + rng.normal(0.0, 0.01, size=photo.shape)
    return np.clip(out, 0.0, 1.0)


def save_image(path: Path, rgb: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    bgr = cv2.cvtColor(np.round(rgb * 255.0).astype(np.uint8), cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, 95] if path.suffix == ".jpg" else []
    if not cv2.imwrite(str(path), bgr, params):
        raise InputError("cannot write the image", path)


def _save_mask(path: Path, mask: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), mask):
        raise InputError("cannot write the mask", path)


def _usid(root: Path, scenes: list[str], n_views: int, h: int, w: int, seed: int) -> None:
    for k, scene in enumerate(scenes):
        rng = np.random.default_rng([seed, 360, k])
        test = root / "output" / scene / "test"
        for i, (photo, mask, _) in enumerate(_views(rng, n_views, h, w)):
            save_image(root / "data" / scene / "test_images" / f"IMG_{i}.jpg", photo)
            _save_mask(test / "ours_30000" / "object_mask" / f"{i:05d}.png", mask)
            for method in METHODS:
                save_image(test / method / "renders" / f"{i:05d}.png", _render(method, photo, mask, rng))
                _save_mask(test / method / "object_mask" / f"{i:05d}.png", mask)


def _spinnerf(root: Path, scenes: list[str], n_test: int, n_train: int, h: int, w: int, seed: int) -> None:
    for k, scene in enumerate(scenes):
        rng = np.random.default_rng([seed, 1, k])
        images = root / "data" / scene / "images"
        for i, (photo, mask, colour) in enumerate(_views(rng, n_test + n_train, h, w)):
            if i < n_test:  # a test view: the scene without the object, and the methods' renders of it
                save_image(images / f"IMG_{i}.jpg", photo)
                for method in METHODS:
                    save_image(root / "output" / scene / method / "renders" / f"{i:05d}.png",
                          _render(method, photo, mask, rng))
            else:  # a training view: the object is there
                inside = (mask.astype(np.float32) / 255.0)[:, :, None]
                save_image(images / f"IMG_{i}.jpg", photo * (1 - inside) + colour * inside)
            _save_mask(images / "label" / f"IMG_{i}.png", (mask > 127).astype(np.uint8))  # 1 = object, as released


def write_inpaint_example(out: str | os.PathLike, *, n_scenes: int = 2, n_views: int = 6, width: int = 160,
                          height: int = 120, seed: int = 0, n_train: int = 4) -> dict[str, Path]:
    """Write both layouts under ``out`` (see the module docstring); returns {"360usid": ..., "spinnerf": ...}.

    n_views: test views per scene (SPIn-NeRF's scenes get ``n_train`` training photographs after them).
    """
    if not 1 <= n_scenes <= len(SCENES):
        raise InputError(f"--n-scenes must be between 1 and {len(SCENES)}, got {n_scenes}")
    if n_views < 1 or n_train < 0:
        raise InputError(f"--n-views must be at least 1, got {n_views}")
    if width < 16 or height < 16:
        raise InputError(f"the images must be at least 16x16 pixels, got {width}x{height}")
    out = Path(out)
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / MARKER).is_file())):
        raise InputError("exists and is not an example folder written by r360gpu (no "
                         f"{MARKER}); give a new folder", out)

    def write(tmp: Path) -> None:
        scenes = list(SCENES[:n_scenes])
        _usid(tmp / "360usid", scenes, n_views, height, width, seed)
        _spinnerf(tmp / "spinnerf", scenes, n_views, n_train, height, width, seed)
        (tmp / MARKER).write_text(json.dumps({"n_scenes": n_scenes, "n_views": n_views, "width": width,
                                              "height": height, "seed": seed, "n_train": n_train}) + "\n")

    written_in_place(out, write)
    return {"360usid": out / "360usid", "spinnerf": out / "spinnerf"}


def written_in_place(out: Path, write) -> None:
    """``write(folder)`` into a folder beside ``out``, then renamed into it (replacing an earlier ``out``), so
    that ``out`` is never half-written; the folder is removed when ``write`` fails."""
    tmp = out.with_name(out.name + ".r360-tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        write(tmp)
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
