"""The cameras of a benchmark's test photographs, so that a splat scene can be rendered where they were taken.

360-USID ships one COLMAP model per scene (``sparse/0``) holding the training and the test
cameras together; AuraFusion360's reader makes a camera a test camera when the image it names
is in ``test_images/``, matched by the file's base name (in its inpainting stage by the stem,
whatever the extension).  SPIn-NeRF's scenes hold the COLMAP model of all 100 photographs.
`photo_cameras` matches each photograph the same way: the camera whose image has the
photograph's base name, else the one whose image has its stem, and scales the camera to the
photograph's size (3DGS renders a test view at the size of its image).

SPIn-NeRF's scenes also hold LLFF's ``poses_bounds.npy``: one row per image of the scene's image
folder in sorted order of file names (as LLFF's loader lists them), 15 numbers of a 3 x 5 matrix
(columns: the camera's down, right and backward axes in the world, its centre, and image height,
width and focal length in pixels) then the near and far bounds.  `llff_cameras` reads it, the
principal point at the image centre as LLFF assumes; `photo_cameras` uses it when given the file
or a scene folder with no COLMAP model.
"""
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path, PurePosixPath

from ..errors import InputError
from .camera import Camera
from .load import load_cameras

#: Largest relative difference of aspect ratio between a camera and its photograph: beyond it the
#: camera was calibrated for other pictures (a crop), and scaling would misplace every pixel.
ASPECT_TOLERANCE = 0.01


def _base(name: str) -> str:
    return PurePosixPath(name.replace("\\", "/")).name


def _stem(name: str) -> str:
    return _base(name).split(".")[0]  # AuraFusion360 strips from the first dot


def photo_size(path: Path) -> tuple[int, int]:
    """(width, height) of an image, from its header."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            return im.size
    except Exception as e:
        raise InputError(f"cannot read image: {e}", path) from None


#: LLFF's camera file, and the image files its loader lists (in sorted order of their names).
POSES_BOUNDS = "poses_bounds.npy"
_LLFF_IMAGES = ("JPG", "jpg", "png")


def llff_cameras(path: str | os.PathLike, images: list[Path]) -> dict[str, Camera]:
    """{image file name: Camera} from LLFF's ``poses_bounds.npy`` whose rows are ``images`` (the image
    folder's files, sorted); InputError naming the file when it is not (N, 17) for N images."""
    import numpy as np

    path = Path(path)
    try:
        a = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read LLFF poses: {e}", path) from None
    if a.ndim != 2 or a.shape[1] != 17 or not np.issubdtype(a.dtype, np.floating) or not np.isfinite(a).all():
        raise InputError(f"not LLFF poses: expected finite (N, 17) floats, got {a.dtype} {a.shape}", path)
    if len(a) != len(images):
        raise InputError(f"{len(a)} poses but {len(images)} images in {images[0].parent if images else 'the folder'} "
                         f"(rows are the images in sorted order, so the counts must agree)", path)
    out = {}
    for row, img in zip(a, images):
        m = row[:15].reshape(3, 5)
        h, w, f = m[:, 4]
        if not (h >= 1 and w >= 1 and f > 0):
            raise InputError(f"image {img.name}: height, width and focal length {h}, {w}, {f} are not positive", path)
        c2w = np.eye(4)
        c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = m[:, 1], m[:, 0], -m[:, 2], m[:, 3]  # OpenCV: right, down, forward
        try:
            out[img.name] = Camera.from_camera_to_world(c2w, f, f, w / 2.0, h / 2.0, int(round(w)), int(round(h)),
                                                        img.name)
        except ValueError as e:
            raise InputError(f"image {img.name}: {e}", path) from None
    return out


def _llff_file(model: Path) -> Path | None:
    if model.is_file() and model.name.endswith(".npy"):
        return model
    if model.is_dir() and (model / POSES_BOUNDS).is_file() and not any(
            (model / d).is_dir() for d in ("sparse/0", "sparse")):
        return model / POSES_BOUNDS
    return None


def _llff_photo_cameras(photos: list[Path], file: Path) -> list[Camera]:
    folder = photos[0].parent
    images = sorted(p for p in folder.iterdir() if p.is_file() and p.name.endswith(_LLFF_IMAGES))
    cams = llff_cameras(file, images)
    return [cams[p.name] if p.name in cams else _no_camera(p, file) for p in photos]


def _no_camera(photo: Path, where) -> Camera:
    raise InputError(f"cannot render this test view: no camera in {where} names this photograph", photo)


def photo_cameras(photos: list[Path], model: str | os.PathLike) -> list[Camera]:
    """One camera per photograph (same order), from the camera set at ``model`` (anything
    `r360gpu.io.load.load_cameras` reads: a COLMAP model, a scene folder holding ``sparse/0``,
    cameras.json, transforms.json), each scaled to its photograph's size and named after it.

    A photograph with no camera, or with two cameras of its stem, is an InputError naming the
    photograph and the camera set.  ``model`` may also be LLFF's ``poses_bounds.npy`` (`llff_cameras`), or
    a folder holding it and no COLMAP model."""
    llff = _llff_file(Path(model))
    if llff is not None:
        return [_fitted(c, p, llff) for c, p in zip(_llff_photo_cameras(photos, llff), photos)]
    cams = load_cameras(model)
    by_base: dict[str, list[Camera]] = {}
    by_stem: dict[str, list[Camera]] = {}
    for c in cams:
        by_base.setdefault(_base(c.name), []).append(c)
        by_stem.setdefault(_stem(c.name), []).append(c)
    out = []
    for p in photos:
        found = by_base.get(p.name) or by_stem.get(_stem(p.name)) or []
        if len(found) != 1:
            problem = (f"no camera in {model} names this photograph (by file name {p.name!r} or stem "
                       f"{_stem(p.name)!r}); {len(cams)} cameras there, e.g. "
                       f"{', '.join(repr(c.name) for c in cams[:3])}" if not found else
                       f"{len(found)} cameras in {model} have its stem {_stem(p.name)!r}: "
                       f"{', '.join(repr(c.name) for c in found)}")
            raise InputError(f"cannot render this test view: {problem}", p)
        out.append(_fitted(found[0], p, model))
    return out


def _fitted(cam: Camera, photo: Path, model) -> Camera:
    """``cam`` scaled to the photograph's size and named after it; InputError for another aspect ratio."""
    w, h = photo_size(photo)
    if abs((w / h) / (cam.width / cam.height) - 1.0) > ASPECT_TOLERANCE:
        raise InputError(f"the photograph is {w}x{h} but its camera {cam.name!r} in {model} is "
                         f"{cam.width}x{cam.height}, another aspect ratio (a cropped photograph?)", photo)
    return replace(cam.resized(w, h), name=photo.name)
