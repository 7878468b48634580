"""COLMAP sparse points (``points3D.bin`` / ``points3D.txt``): reader and writer.

Only the positions are read: gsplat's world normalisation
(:func:`r360gpu.io.frames.gsplat_frame`) aligns the world to their principal
axes.  Points are returned in increasing ``POINT3D_ID`` order, the order
gsplat's COLMAP parser builds its point array in.

Binary layout (little-endian), as COLMAP's ``read_write_model``: uint64
count, then per point uint64 point3D_id, float64 xyz[3], uint8 rgb[3],
float64 error, uint64 track_length, then track_length x (int32 image_id,
int32 point2D_idx).  Text: one line per point, ``POINT3D_ID X Y Z R G B
ERROR [IMAGE_ID POINT2D_IDX ...]``; ``#`` starts a comment line.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..util.atomic import write_bytes, write_text

_HEAD = struct.Struct("<Q3d3BdQ")
_U64 = struct.Struct("<Q")
_TRACK_ELEMENT_BYTES = 8


def points3d_file(folder: str | os.PathLike) -> Path | None:
    """The ``points3D`` file of a COLMAP model folder (``.bin`` preferred), or None."""
    folder = Path(folder)
    for ext in (".bin", ".txt"):
        if (folder / f"points3D{ext}").is_file():
            return folder / f"points3D{ext}"
    return None


def read_points3d(path: str | os.PathLike) -> np.ndarray:
    """(N, 3) float64 point positions of a ``points3D.bin`` / ``.txt``, by increasing id."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", p) from None
    if p.suffix.lower() == ".bin":
        ids, xyz = _read_binary(data, p)
    else:
        ids, xyz = _read_text(data, p)
    if len(set(ids)) != len(ids):
        raise InputError("duplicate POINT3D_ID", p)
    order = np.argsort(np.asarray(ids, dtype=np.uint64), kind="stable")
    out = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)[order]
    if not np.isfinite(out).all():
        raise InputError("non-finite point coordinates", p)
    return out


def _read_binary(data: bytes, p: Path) -> tuple[list[int], list]:
    if len(data) < _U64.size:
        raise InputError("truncated while reading the point count", p)
    (n,), pos = _U64.unpack_from(data, 0), _U64.size
    ids, xyz = [], []
    for i in range(n):
        if pos + _HEAD.size > len(data):
            raise InputError(f"truncated while reading point {i} of {n}", p)
        pid, x, y, z, _r, _g, _b, _err, track = _HEAD.unpack_from(data, pos)
        pos += _HEAD.size + track * _TRACK_ELEMENT_BYTES
        if pos > len(data):
            raise InputError(f"truncated while reading the track of point {i} of {n}", p)
        ids.append(pid)
        xyz.append((x, y, z))
    if pos != len(data):
        raise InputError(f"{len(data) - pos} bytes after the {n} points the count declares (wrong count?)", p)
    return ids, xyz


def _read_text(data: bytes, p: Path) -> tuple[list[int], list]:
    ids, xyz = [], []
    for lineno, raw in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        try:
            if len(parts) < 8 or (len(parts) - 8) % 2:
                raise ValueError
            ids.append(int(parts[0]))
            xyz.append(tuple(float(v) for v in parts[1:4]))
        except ValueError:
            raise InputError(f"line {lineno}: expected POINT3D_ID X Y Z R G B ERROR [IMAGE_ID POINT2D_IDX ...]",
                             p) from None
    return ids, xyz


def save_points3d(folder: str | os.PathLike, xyz, binary: bool = True) -> Path:
    """Write ``xyz`` (N, 3) as ``points3D.bin`` (or ``.txt``) in ``folder`` (ids 1..N, grey, no
    tracks), atomically; returns the file."""
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    folder = Path(folder)
    if binary:
        parts = [_U64.pack(len(xyz))]
        parts += [_HEAD.pack(i, *map(float, pt), 128, 128, 128, 0.0, 0) for i, pt in enumerate(xyz, 1)]
        path = folder / "points3D.bin"
        write_bytes(path, b"".join(parts))
    else:
        lines = ["# 3D point list: POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]"]
        lines += [f"{i} {pt[0]!r} {pt[1]!r} {pt[2]!r} 128 128 128 0.0" for i, pt in enumerate(xyz.tolist(), 1)]
        path = folder / "points3D.txt"
        write_text(path, "\n".join(lines) + "\n")
    return path
