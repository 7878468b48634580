"""The cameras of a benchmark's test photographs, so that a splat scene can be rendered where they were taken.

360-USID ships one COLMAP model per scene (``sparse/0``) holding the training and the test
cameras together; AuraFusion360's reader makes a camera a test camera when the image it names
is in ``test_images/``, matched by the file's base name (in its inpainting stage by the stem,
whatever the extension).  SPIn-NeRF's scenes hold the COLMAP model of all 100 photographs.
`photo_cameras` matches each photograph the same way: the camera whose image has the
photograph's base name, else the one whose image has its stem, and scales the camera to the
photograph's size (3DGS renders a test view at the size of its image).
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


def photo_cameras(photos: list[Path], model: str | os.PathLike) -> list[Camera]:
    """One camera per photograph (same order), from the camera set at ``model`` (anything
    `r360gpu.io.load.load_cameras` reads: a COLMAP model, a scene folder holding ``sparse/0``,
    cameras.json, transforms.json), each scaled to its photograph's size and named after it.

    A photograph with no camera, or with two cameras of its stem, is an InputError naming the
    photograph and the camera set."""
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
        cam = found[0]
        w, h = photo_size(p)
        if abs((w / h) / (cam.width / cam.height) - 1.0) > ASPECT_TOLERANCE:
            raise InputError(f"the photograph is {w}x{h} but its camera {cam.name!r} in {model} is "
                             f"{cam.width}x{cam.height}, another aspect ratio (a cropped photograph?)", p)
        out.append(replace(cam.resized(w, h), name=p.name))
    return out
