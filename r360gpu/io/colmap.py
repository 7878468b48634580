"""COLMAP sparse models (``cameras`` + ``images``, binary or text): reader and writer.

COLMAP stores, per registered image, ``qvec = (qw, qx, qy, qz)`` and ``tvec``
of the WORLD-TO-CAMERA transform in OpenCV axes, i.e. exactly
``Camera.R = quat_to_rotmat(qvec)`` and ``Camera.t = tvec``; its pixel
convention (centre of the top-left pixel at (0.5, 0.5)) is the one
:mod:`r360gpu.io.camera` uses, so intrinsics are taken as they are.

Binary layout (little-endian), as COLMAP's ``read_write_model``:

* ``cameras.bin``: uint64 count, then per camera int32 camera_id,
  int32 model_id, uint64 width, uint64 height, float64 params[n(model)].
* ``images.bin``: uint64 count, then per image int32 image_id,
  float64 qvec[4], float64 tvec[3], int32 camera_id, the name as
  NUL-terminated bytes, uint64 n_points2D, then n_points2D x
  (float64 x, float64 y, int64 point3D_id).

Text: ``cameras.txt`` lines ``CAMERA_ID MODEL WIDTH HEIGHT PARAMS...``;
``images.txt`` two lines per image, ``IMAGE_ID QW QX QY QZ TX TY TZ
CAMERA_ID NAME`` then the (possibly empty) ``X Y POINT3D_ID ...`` line;
``#`` starts a comment line.

Distorted models render as their pinhole part (fx, fy, cx, cy); one
R360Warning names the models whose distortion is thereby ignored (radial /
OpenCV-type models whose distortion parameters are all zero are exact and
not reported; fisheye models always are).
"""
from __future__ import annotations

import os
import struct
import warnings
from pathlib import Path
from typing import NamedTuple, Sequence

import numpy as np

from .paths import read_error
from ..errors import InputError, R360Warning
from ..util.atomic import write_bytes, write_text
from .camera import Camera, make_camera
from .rotation import quat_to_rotmat, rotmat_to_quat

# model_id -> (name, number of params, index of fx, index of fy, index of cx, index of cy)
_MODELS = {
    0: ("SIMPLE_PINHOLE", 3, 0, 0, 1, 2),
    1: ("PINHOLE", 4, 0, 1, 2, 3),
    2: ("SIMPLE_RADIAL", 4, 0, 0, 1, 2),
    3: ("RADIAL", 5, 0, 0, 1, 2),
    4: ("OPENCV", 8, 0, 1, 2, 3),
    5: ("OPENCV_FISHEYE", 8, 0, 1, 2, 3),
    6: ("FULL_OPENCV", 12, 0, 1, 2, 3),
    7: ("FOV", 5, 0, 1, 2, 3),
    8: ("SIMPLE_RADIAL_FISHEYE", 4, 0, 0, 1, 2),
    9: ("RADIAL_FISHEYE", 5, 0, 0, 1, 2),
    10: ("THIN_PRISM_FISHEYE", 12, 0, 1, 2, 3),
    11: ("RAD_TAN_THIN_PRISM_FISHEYE", 16, 0, 1, 2, 3),
    12: ("SIMPLE_DIVISION", 4, 0, 0, 1, 2),
    13: ("DIVISION", 5, 0, 1, 2, 3),
    14: ("SIMPLE_FISHEYE", 3, 0, 0, 1, 2),
    15: ("FISHEYE", 4, 0, 1, 2, 3),
    16: ("EUCM", 6, 0, 1, 2, 3),
}
_MODEL_BY_NAME = {v[0]: k for k, v in _MODELS.items()}
_EXACT = {"SIMPLE_PINHOLE", "PINHOLE"}
# Perspective models that reduce to a pinhole when their distortion parameters are zero.
_ZERO_DISTORTION_IS_PINHOLE = {"SIMPLE_RADIAL", "RADIAL", "OPENCV", "FULL_OPENCV", "FOV",
                               "SIMPLE_DIVISION", "DIVISION"}

_CAMERA_HEAD = struct.Struct("<iiQQ")
_IMAGE_HEAD = struct.Struct("<i7di")
_U64 = struct.Struct("<Q")
_POINT2D_BYTES = 24


class ColmapCamera(NamedTuple):
    model: str
    width: int
    height: int
    params: tuple[float, ...]


class ColmapImage(NamedTuple):
    image_id: int
    qvec: tuple[float, float, float, float]
    tvec: tuple[float, float, float]
    camera_id: int
    name: str


# ---------------------------------------------------------------------------- reading


def read_cameras_binary(path: str | os.PathLike) -> dict[int, ColmapCamera]:
    """Intrinsics from ``cameras.bin`` keyed by camera id (model by name)."""
    data = _read(path)
    r = _Reader(data, path)
    out = {}
    for _ in range(r.u64("camera count")):
        cam_id, model_id, width, height = r.unpack(_CAMERA_HEAD, "camera record")
        if model_id not in _MODELS:
            raise InputError(f"camera {cam_id}: unsupported camera model id {model_id}", path)
        name, nparams = _MODELS[model_id][:2]
        params = r.unpack(struct.Struct(f"<{nparams}d"), f"camera {cam_id} parameters")
        out[cam_id] = ColmapCamera(name, width, height, tuple(params))
    r.expect_end()
    return out


def read_images_binary(path: str | os.PathLike) -> list[ColmapImage]:
    """Registered images from ``images.bin`` in file order."""
    data = _read(path)
    r = _Reader(data, path)
    out = []
    for _ in range(r.u64("image count")):
        vals = r.unpack(_IMAGE_HEAD, "image record")
        name = r.cstring("image name")
        n_pts = r.u64("points2D count")
        r.skip(n_pts * _POINT2D_BYTES, f"points2D of image {name!r}")
        out.append(ColmapImage(vals[0], tuple(vals[1:5]), tuple(vals[5:8]), vals[8], name))
    r.expect_end()
    return out


def read_cameras_text(path: str | os.PathLike) -> dict[int, ColmapCamera]:
    """Intrinsics from ``cameras.txt`` keyed by camera id."""
    out = {}
    for lineno, line in _data_lines(path):
        words = line.split()
        try:
            cam_id, model, width, height = int(words[0]), words[1], int(words[2]), int(words[3])
            params = tuple(float(w) for w in words[4:])
        except (ValueError, IndexError):
            raise InputError(f"line {lineno}: malformed camera line {line!r}", path) from None
        if model not in _MODEL_BY_NAME:
            raise InputError(f"line {lineno}: unsupported camera model {model!r}", path)
        expect = _MODELS[_MODEL_BY_NAME[model]][1]
        if len(params) != expect:
            raise InputError(f"line {lineno}: {model} needs {expect} parameters, got {len(params)}", path)
        out[cam_id] = ColmapCamera(model, width, height, params)
    return out


def read_images_text(path: str | os.PathLike) -> list[ColmapImage]:
    """Registered images from ``images.txt`` in file order."""
    lines = _text(path).splitlines()
    out = []
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        i += 1
        if not line or line.startswith("#"):
            continue
        words = line.split(None, 9)  # the name is the rest of the line, its own spaces kept as written
        try:
            image_id = int(words[0])
            vals = [float(w) for w in words[1:8]]
            cam_id = int(words[8])
            name = words[9] if len(words) > 9 else ""
        except (ValueError, IndexError):
            raise InputError(f"line {i}: malformed image line {line!r}", path) from None
        if len(vals) != 7 or not name:
            raise InputError(f"line {i}: malformed image line {line!r}", path)
        # The next line lists the image's 2D points as (x, y, point3D_id) triples.
        points = lines[i].split() if i < len(lines) else []
        if len(points) % 3:
            raise InputError(
                f"line {i + 1}: expected the POINTS2D line (x y point3D_id triples) of image "
                f"{name!r}, got {len(points)} values", path)
        i += 1
        out.append(ColmapImage(image_id, tuple(vals[:4]), tuple(vals[4:]), cam_id, name))
    return out


def load_colmap(path: str | os.PathLike) -> list[Camera]:
    """Cameras of a COLMAP sparse model, in the order of the images file.

    path: a model folder (e.g. ``sparse/0``) holding ``cameras`` and ``images``
    as ``.bin`` (preferred when both exist) or ``.txt``, or one of those files
    (its extension picks the format of both).
    """
    p = Path(path)
    if p.is_dir():
        ext = ".bin" if (p / "cameras.bin").is_file() and (p / "images.bin").is_file() else ".txt"
        folder = p
    elif p.is_file():
        ext, folder = p.suffix, p.parent
    else:
        raise InputError("no such file or folder", path)
    cam_file, img_file = folder / f"cameras{ext}", folder / f"images{ext}"
    for f in (cam_file, img_file):
        if not f.is_file():
            raise InputError(f"COLMAP model is missing {f.name}", folder)
    if ext == ".bin":
        intrinsics, images = read_cameras_binary(cam_file), read_images_binary(img_file)
    elif ext == ".txt":
        intrinsics, images = read_cameras_text(cam_file), read_images_text(img_file)
    else:
        raise InputError("not a COLMAP cameras/images .bin or .txt file", path)
    return _to_cameras(intrinsics, images, img_file)


def _to_cameras(intrinsics: dict[int, ColmapCamera], images: list[ColmapImage], source: Path) -> list[Camera]:
    distorted: set[str] = set()
    out = []
    for im in images:
        if im.camera_id not in intrinsics:
            raise InputError(f"image {im.name!r} refers to camera {im.camera_id}, which is not defined", source)
        cam = intrinsics[im.camera_id]
        _, _, ifx, ify, icx, icy = _MODELS[_MODEL_BY_NAME[cam.model]]
        if cam.model not in _EXACT:
            extra = cam.params[max(ifx, ify, icx, icy) + 1:]
            if cam.model not in _ZERO_DISTORTION_IS_PINHOLE or any(v != 0 for v in extra):
                distorted.add(cam.model)
        q = np.asarray(im.qvec, dtype=np.float64)
        if not (np.isfinite(q).all() and np.linalg.norm(q) > 1e-8):
            raise InputError(f"image {im.name!r}: invalid qvec {im.qvec}", source)
        p = cam.params
        out.append(make_camera(source, quat_to_rotmat(q), im.tvec, p[ifx], p[ify], p[icx], p[icy],
                               cam.width, cam.height, im.name))
    if distorted:
        warnings.warn(
            f"{source}: camera model(s) {', '.join(sorted(distorted))} have lens distortion; "
            f"rendering with their pinhole part (fx, fy, cx, cy), distortion ignored",
            R360Warning, stacklevel=3)
    return out


def _read(path: str | os.PathLike) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise read_error(e, path) from None


def _text(path: str | os.PathLike) -> str:
    """A COLMAP text file as text: UTF-8 (a BOM is dropped); other bytes are an InputError, since an
    image name decoded wrongly would silently match no mask."""
    try:
        return _read(path).decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text (byte {e.start}); COLMAP text models are UTF-8", path) from None


def _data_lines(path: str | os.PathLike):
    for lineno, raw in enumerate(_text(path).splitlines(), 1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield lineno, line


class _Reader:
    """Sequential reader of a COLMAP binary file; running out of bytes is an InputError."""

    def __init__(self, data: bytes, path):
        self.data, self.path, self.pos = data, path, 0

    def _need(self, n: int, what: str) -> None:
        if self.pos + n > len(self.data):
            raise InputError(f"truncated while reading {what}", self.path)

    def unpack(self, st: struct.Struct, what: str) -> tuple:
        self._need(st.size, what)
        vals = st.unpack_from(self.data, self.pos)
        self.pos += st.size
        return vals

    def u64(self, what: str) -> int:
        return self.unpack(_U64, what)[0]

    def skip(self, n: int, what: str) -> None:
        self._need(n, what)
        self.pos += n

    def cstring(self, what: str) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise InputError(f"truncated while reading {what}", self.path)
        s = self.data[self.pos:end].decode("utf-8", errors="replace")
        self.pos = end + 1
        return s

    def expect_end(self) -> None:
        if self.pos != len(self.data):
            raise InputError(
                f"{len(self.data) - self.pos} bytes after the records the count declares "
                f"(wrong count?)", self.path)


# ---------------------------------------------------------------------------- writing


def save_colmap(folder: str | os.PathLike, cameras: Sequence[Camera], binary: bool = True) -> None:
    """Write ``cameras`` as a COLMAP sparse model in ``folder`` (atomically, file by file).

    One PINHOLE camera per image (camera_id = image_id = index + 1), the
    image name is ``Camera.name``, no 2D points, and an empty ``points3D``
    file so that tools requiring one (e.g. INRIA 3DGS) accept the folder.
    ``binary`` selects ``.bin`` or ``.txt`` files.
    """
    folder = Path(folder)
    rows = []
    for i, cam in enumerate(cameras, 1):
        if "\0" in cam.name or "\n" in cam.name or not cam.name.strip():
            raise ValueError(f"camera name {cam.name!r} cannot be stored in a COLMAP model")
        rows.append((i, cam, rotmat_to_quat(cam.R)))
    if binary:
        cam_b = [_U64.pack(len(rows))]
        img_b = [_U64.pack(len(rows))]
        for i, cam, q in rows:
            cam_b.append(_CAMERA_HEAD.pack(i, _MODEL_BY_NAME["PINHOLE"], cam.width, cam.height))
            cam_b.append(struct.pack("<4d", cam.fx, cam.fy, cam.cx, cam.cy))
            img_b.append(_IMAGE_HEAD.pack(i, *q, *cam.t, i))
            img_b.append(cam.name.encode("utf-8") + b"\0")
            img_b.append(_U64.pack(0))
        write_bytes(folder / "cameras.bin", b"".join(cam_b))
        write_bytes(folder / "images.bin", b"".join(img_b))
        write_bytes(folder / "points3D.bin", _U64.pack(0))
    else:
        cam_t = ["# Camera list: CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
                 f"# Number of cameras: {len(rows)}"]
        img_t = ["# Image list, two lines per image:",
                 "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
                 "#   POINTS2D[] as (X, Y, POINT3D_ID)",
                 f"# Number of images: {len(rows)}"]
        for i, cam, q in rows:
            cam_t.append(" ".join([str(i), "PINHOLE", str(cam.width), str(cam.height),
                                   *(repr(float(v)) for v in (cam.fx, cam.fy, cam.cx, cam.cy))]))
            img_t.append(" ".join([str(i), *(repr(float(v)) for v in (*q, *cam.t)), str(i), cam.name]))
            img_t.append("")
        write_text(folder / "cameras.txt", "\n".join(cam_t) + "\n")
        write_text(folder / "images.txt", "\n".join(img_t) + "\n")
        write_text(folder / "points3D.txt", "# 3D point list (empty)\n")
