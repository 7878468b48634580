"""nerfstudio / instant-ngp / NeRF-synthetic ``transforms.json``: reader and writer.

Each frame's ``transform_matrix`` (4x4, or 3x4) is CAMERA-TO-WORLD in
**OpenGL/Blender camera axes** (x right, y up, z backwards: the camera looks
along -z).  The conversion to the OpenCV axes of :class:`Camera` negates the
camera's y and z axes: ``c2w_cv = c2w_gl @ diag(1, -1, -1, 1)``; this module
is the only place that does it.  The world frame is used as it is (nerfstudio's
``applied_transform`` and instant-ngp's ``scale``/``offset`` describe how
that world relates to others and are not applied here).  A splat scene
exported in another frame (nerfstudio's dataparser frame, gsplat's
normalised world) is rendered with the cameras moved into its frame by the
bundle's ``frame`` key: :mod:`r360gpu.io.frames`.

Intrinsics, each looked up in the frame first and then at the top level:

* ``w``, ``h``: image size in pixels.  If absent, the size is read from the
  frame's image (``file_path`` relative to the JSON file, trying ``.png``
  appended as NeRF-synthetic files omit it).
* ``fl_x``, else ``0.5 * w / tan(0.5 * camera_angle_x)``.
* ``fl_y``, else from ``camera_angle_y`` likewise, else ``fl_x``.
* ``cx``, ``cy``, else ``w / 2``, ``h / 2`` (pixel-corner convention of
  :mod:`r360gpu.io.camera`, as nerfstudio and instant-ngp use).

Non-zero distortion (``k1..k4``, ``p1``, ``p2``), a fisheye ``camera_model``
(``OPENCV_FISHEYE``) or ``is_fisheye`` render as the pinhole part with one
R360Warning; other non-perspective models (e.g. ``EQUIRECTANGULAR``) are an
InputError.  ``Camera.name`` is ``file_path`` without a leading ``./``.
"""
from __future__ import annotations

import math
import os
import struct
import warnings
from pathlib import Path
from typing import Sequence

import cv2
import numpy as np

from ..errors import InputError, R360Warning
from ..util.atomic import write_json
from .camera import Camera, checked_rotation, make_camera
from .jsonfile import read_json

# OpenGL camera axes -> OpenCV camera axes (right-multiplied onto camera-to-world).
GL_TO_CV = np.diag([1.0, -1.0, -1.0, 1.0])
_PERSPECTIVE = {"PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "SIMPLE_RADIAL", "RADIAL", "PERSPECTIVE"}
_FISHEYE = {"OPENCV_FISHEYE", "FISHEYE"}
_DISTORTION_KEYS = ("k1", "k2", "k3", "k4", "p1", "p2")


def is_transforms_json(obj) -> bool:
    """True for a parsed JSON document with a ``frames`` list."""
    return isinstance(obj, dict) and isinstance(obj.get("frames"), list)


def load_transforms_json(path: str | os.PathLike) -> list[Camera]:
    """Cameras of a transforms.json, in frame order; see the module docstring."""
    return cameras_from_transforms(read_json(path), path)


def cameras_from_transforms(doc, path: str | os.PathLike) -> list[Camera]:
    """Decode an already parsed transforms.json document (``path`` names it in errors and
    anchors relative image paths)."""
    if not is_transforms_json(doc):
        raise InputError("transforms.json must be an object with a 'frames' list", path)
    if not doc["frames"]:
        raise InputError("transforms.json has no frames", path)
    base = Path(path).parent
    distorted: set[str] = set()
    out = []
    for i, frame in enumerate(doc["frames"]):
        if not isinstance(frame, dict):
            raise InputError(f"frame {i} is not an object", path)

        def get(key, default=None, _frame=frame):
            return _frame.get(key, doc.get(key, default))

        name = str(frame.get("file_path", f"frame_{i:05d}"))
        name = name[2:] if name.startswith("./") else name
        what = f"frame {i} ({name!r})"
        if "transform_matrix" not in frame:
            raise InputError(f"{what}: no transform_matrix", path)
        try:
            m = np.asarray(frame["transform_matrix"], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{what}: transform_matrix is not a numeric matrix", path) from None
        if m.shape not in ((4, 4), (3, 4)):
            raise InputError(f"{what}: transform_matrix must be 4x4 or 3x4, got {m.shape}", path)
        c2w = np.eye(4)
        c2w[:3, :] = m[:3, :]
        c2w[:3, :3] = checked_rotation(c2w[:3, :3], path, what)
        c2w_cv = c2w @ GL_TO_CV

        model = str(get("camera_model", "OPENCV")).upper()
        if model in _FISHEYE or get("is_fisheye", False):
            distorted.add(model if model in _FISHEYE else "fisheye")
        elif model not in _PERSPECTIVE:
            raise InputError(f"{what}: camera_model {model!r} is not a perspective camera", path)
        elif any(_num(get(k, 0), k, what, path) != 0 for k in _DISTORTION_KEYS):
            distorted.add(f"{model} with non-zero distortion")

        w, h = get("w"), get("h")
        if w is None or h is None:
            w, h = _image_size(base, name, path, what)
        w, h = _num(w, "w", what, path), _num(h, "h", what, path)
        fx = _focal(get("fl_x"), get("camera_angle_x"), w, "x", what, path)
        fy = _focal(get("fl_y"), get("camera_angle_y"), h, "y", what, path, fallback=fx)
        cx = _num(get("cx", w / 2), "cx", what, path)
        cy = _num(get("cy", h / 2), "cy", what, path)
        r = c2w_cv[:3, :3].T
        out.append(make_camera(path, r, -r @ c2w_cv[:3, 3], fx, fy, cx, cy, w, h, name))
    if distorted:
        warnings.warn(
            f"{os.fspath(path)}: {', '.join(sorted(distorted))} cameras; rendering with their "
            f"pinhole part (fl_x, fl_y, cx, cy), distortion ignored", R360Warning, stacklevel=3)
    return out


def _num(v, key: str, what: str, path) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{what}: {key} must be a number, got {v!r}", path)
    return v


def _focal(fl, angle, size, axis: str, what: str, path, fallback=None) -> float:
    if fl is not None:
        return _num(fl, f"fl_{axis}", what, path)
    if angle is not None:
        a = _num(angle, f"camera_angle_{axis}", what, path)
        if not 0 < a < math.pi:
            raise InputError(f"{what}: camera_angle_{axis} = {a} is not in (0, pi)", path)
        return 0.5 * size / math.tan(0.5 * a)
    if fallback is not None:
        return fallback
    raise InputError(f"{what}: no focal length (fl_{axis} or camera_angle_{axis})", path)


def _image_size(base: Path, name: str, path, what: str) -> tuple[int, int]:
    for candidate in (base / name, base / (name + ".png")):
        if candidate.is_file():
            size = _png_size(candidate)
            if size is None:
                img = cv2.imread(str(candidate), cv2.IMREAD_UNCHANGED)
                if img is None:
                    raise InputError(f"{what}: cannot read image {candidate} to get its size", path)
                size = (img.shape[1], img.shape[0])
            return size
    raise InputError(f"{what}: no 'w'/'h' given and image {name!r} not found beside the file", path)


def _png_size(file: Path) -> tuple[int, int] | None:
    # A PNG's first chunk is IHDR: width and height are big-endian uint32 at bytes 16..24.
    with open(file, "rb") as f:
        head = f.read(24)
    if len(head) == 24 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        return struct.unpack(">II", head[16:24])
    return None


def save_transforms_json(path: str | os.PathLike, cameras: Sequence[Camera]) -> None:
    """Write ``cameras`` as a nerfstudio-style transforms.json (atomically).

    ``camera_model`` PINHOLE, per-frame ``fl_x, fl_y, cx, cy, w, h``,
    ``file_path`` = ``Camera.name``, ``transform_matrix`` camera-to-world in
    OpenGL axes.
    """
    frames = []
    for cam in cameras:
        c2w_gl = cam.camera_to_world @ GL_TO_CV  # GL_TO_CV is its own inverse
        frames.append({
            "file_path": cam.name,
            "fl_x": cam.fx, "fl_y": cam.fy, "cx": cam.cx, "cy": cam.cy,
            "w": cam.width, "h": cam.height,
            "transform_matrix": c2w_gl.tolist(),
        })
    write_json(path, {"camera_model": "PINHOLE", "frames": frames})
