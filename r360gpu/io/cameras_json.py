"""``cameras.json`` as written by INRIA 3DGS training: reader and writer.

INRIA's ``camera_to_JSON`` builds ``Rt = [[R_w2c, T], [0, 1]]`` (its
``Camera.R`` is the transposed world-to-camera rotation of COLMAP, ``T`` the
COLMAP tvec), inverts it, and stores the INVERSE's blocks: ``rotation`` is
the CAMERA-TO-WORLD rotation (a list of rows) and ``position`` the camera
centre in world coordinates, both in OpenCV camera axes (INRIA converts
Blender/NeRF-synthetic poses to these axes before training).  So here
``Camera.R = rotation^T`` and ``Camera.t = -R @ position``.

Each entry: ``id, img_name, width, height, position, rotation, fx, fy``.
INRIA writes no principal point (its rasteriser assumes the image centre),
so ``cx, cy`` default to ``width / 2, height / 2``; entries with ``cx``/``cy``
keys (written by some forks, and by :func:`save_cameras_json`) use them.
``width``/``height`` are those of the images the model was trained on.
"""
from __future__ import annotations

import os
from typing import Sequence

import numpy as np

from ..errors import InputError
from ..util.atomic import write_json
from .camera import Camera, checked_rotation, make_camera
from .jsonfile import read_json


def is_cameras_json(obj) -> bool:
    """True for a parsed JSON document shaped like INRIA's cameras.json (a list of camera dicts)."""
    return isinstance(obj, list) and bool(obj) and all(isinstance(e, dict) and "rotation" in e for e in obj)


def load_cameras_json(path: str | os.PathLike) -> list[Camera]:
    """Cameras of an INRIA ``cameras.json``, in file order."""
    return cameras_from_json(read_json(path), path)


def cameras_from_json(doc, path: str | os.PathLike) -> list[Camera]:
    """Decode an already parsed cameras.json document (``path`` names it in errors)."""
    if not isinstance(doc, list):
        raise InputError("cameras.json must hold a list of cameras", path)
    if not doc:
        raise InputError("cameras.json holds no cameras", path)
    out = []
    for i, e in enumerate(doc):
        if not isinstance(e, dict):
            raise InputError(f"entry {i} is not an object", path)
        missing = [k for k in ("img_name", "width", "height", "position", "rotation", "fx", "fy") if k not in e]
        if missing:
            raise InputError(f"entry {i}: missing keys {', '.join(missing)}", path)
        name = str(e["img_name"])
        try:
            centre = np.asarray(e["position"], dtype=np.float64)
            rot = np.asarray(e["rotation"], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"camera {name!r}: position/rotation are not numeric arrays", path) from None
        if centre.shape != (3,):
            raise InputError(f"camera {name!r}: position must have 3 numbers", path)
        r_c2w = checked_rotation(rot, path, f"camera {name!r}")
        r = r_c2w.T
        w, h = e["width"], e["height"]
        cx = e.get("cx", _half(w))
        cy = e.get("cy", _half(h))
        out.append(_camera(path, r, -r @ centre, e["fx"], e["fy"], cx, cy, w, h, name))
    return out


def _half(v):
    return v / 2 if isinstance(v, (int, float)) and not isinstance(v, bool) else v


def _camera(path, r, t, fx, fy, cx, cy, w, h, name) -> Camera:
    for key, val in (("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy), ("width", w), ("height", h)):
        if isinstance(val, bool) or not isinstance(val, (int, float)):
            raise InputError(f"camera {name!r}: {key} must be a number, got {val!r}", path)
    return make_camera(path, r, t, fx, fy, cx, cy, w, h, name)


def save_cameras_json(path: str | os.PathLike, cameras: Sequence[Camera]) -> None:
    """Write ``cameras`` in INRIA's cameras.json layout (atomically), adding ``cx``, ``cy``."""
    doc = []
    for i, cam in enumerate(cameras):
        doc.append({
            "id": i,
            "img_name": cam.name,
            "width": cam.width,
            "height": cam.height,
            "position": cam.center.tolist(),
            "rotation": cam.R.T.tolist(),
            "fy": cam.fy,
            "fx": cam.fx,
            "cx": cam.cx,
            "cy": cam.cy,
        })
    write_json(path, doc)
