"""One entry point per kind of input: :func:`load_gaussians` and :func:`load_cameras`.

They pick the format from the path (extension, folder contents) and, where
the extension is shared, from the content, then call the format's module.
"""
from __future__ import annotations

import os
import re
from collections import Counter
from pathlib import Path

from ..errors import InputError
from .camera import Camera
from .cameras_json import cameras_from_json, is_cameras_json
from .colmap import load_colmap
from .compressed_ply import gaussians_from_compressed_ply, is_compressed_ply
from .gaussians import Gaussians
from .inria_ply import gaussians_from_inria_ply
from .jsonfile import read_json
from .ply import read_ply
from .splat import load_splat
from .transforms_json import cameras_from_transforms, is_transforms_json

_PLY_MAGIC = (b"ply\n", b"ply\r\n")
_KNOWN_UNSUPPORTED = {".ksplat", ".spz", ".sog", ".splatv", ".glb", ".npz"}
_ITERATION_DIR = re.compile(r"iteration_(\d+)$")


def load_gaussians(path: str | os.PathLike) -> Gaussians:
    """Load a Gaussian-splat scene.

    Accepted: an INRIA 3DGS ``.ply`` (any PLY encoding), a PlayCanvas/SuperSplat
    ``.compressed.ply`` (recognised by its content, whatever the name), a
    ``.splat`` file, or an INRIA output folder (``point_cloud/iteration_*/
    point_cloud.ply``, highest iteration).  Anything else is an InputError.
    """
    p = Path(path)
    if p.is_dir():
        p = latest_inria_iteration(p)
    if not p.is_file():
        raise InputError("no such file", p)
    suffix = p.suffix.lower()
    if suffix == ".splat":
        return load_splat(p)
    if suffix == ".ply" or _starts_with(p, _PLY_MAGIC):
        ply = read_ply(p)
        if is_compressed_ply(ply):
            return gaussians_from_compressed_ply(ply)
        return gaussians_from_inria_ply(ply)
    hint = " (a splat format r360gpu does not read)" if suffix in _KNOWN_UNSUPPORTED else ""
    raise InputError(
        f"unknown Gaussian-splat format{hint}; expected an INRIA 3DGS .ply, a .compressed.ply "
        f"or a .splat file", p)


def latest_inria_iteration(folder: Path) -> Path:
    runs = []
    pc = folder / "point_cloud"
    if pc.is_dir():
        for d in pc.iterdir():
            m = _ITERATION_DIR.match(d.name)
            if m and (d / "point_cloud.ply").is_file():
                runs.append((int(m.group(1)), d / "point_cloud.ply"))
    if not runs:
        raise InputError("folder has no point_cloud/iteration_*/point_cloud.ply (not an INRIA 3DGS "
                         "output folder); pass the scene file itself", folder)
    return max(runs)[1]


def _starts_with(p: Path, prefixes: tuple[bytes, ...]) -> bool:
    try:
        with open(p, "rb") as f:
            head = f.read(8)
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", p) from None
    return head.startswith(prefixes)


def load_cameras(path: str | os.PathLike) -> list[Camera]:
    """Load the evaluation cameras, sorted by ``Camera.name``.

    Accepted:

    * a COLMAP model: a folder holding ``cameras``/``images`` ``.bin`` or
      ``.txt``, a folder holding ``sparse/0`` (or ``sparse``) with them, or
      one of those files;
    * INRIA's ``cameras.json`` (a JSON list of cameras);
    * a ``transforms.json`` (a JSON object with ``frames``), whatever the
      file's name (e.g. ``transforms_test.json``);
    * a folder holding exactly one of ``cameras.json`` / ``transforms.json``
      and no COLMAP model.

    A folder holding more than one kind is an InputError (their world frames
    may differ: pass the file).  Duplicate camera names are an InputError
    (views are matched to masks and renderings by name).
    """
    p = Path(path)
    if p.is_dir():
        cams = _cameras_from_folder(p)
    elif p.is_file():
        cams = _cameras_from_file(p)
    else:
        raise InputError("no such file or folder", p)
    dupes = sorted(name for name, k in Counter(c.name for c in cams).items() if k > 1)
    if dupes:
        raise InputError(f"duplicate camera names: {', '.join(map(repr, dupes[:5]))}", p)
    return sorted(cams, key=lambda c: c.name)


def _is_colmap_dir(d: Path) -> bool:
    return any((d / f"cameras{e}").is_file() and (d / f"images{e}").is_file() for e in (".bin", ".txt"))


def _cameras_from_folder(p: Path) -> list[Camera]:
    found = []
    for d in (p, p / "sparse" / "0", p / "sparse"):
        if _is_colmap_dir(d):
            found.append(d)
            break
    found += [p / f for f in ("cameras.json", "transforms.json") if (p / f).is_file()]
    if not found:
        raise InputError("no cameras found: expected a COLMAP model (cameras/images .bin or .txt, "
                         "possibly under sparse/0), cameras.json or transforms.json", p)
    if len(found) > 1:
        listed = ", ".join(str(f.relative_to(p)) or "." for f in found)
        raise InputError(f"ambiguous: several camera sets ({listed}); pass one of them", p)
    return load_colmap(found[0]) if found[0].is_dir() else _cameras_from_file(found[0])


def _cameras_from_file(p: Path) -> list[Camera]:
    suffix = p.suffix.lower()
    if suffix in (".bin", ".txt") and p.stem in ("cameras", "images"):
        return load_colmap(p)
    if suffix == ".json":
        doc = read_json(p)
        if is_transforms_json(doc):
            return cameras_from_transforms(doc, p)
        if is_cameras_json(doc):
            return cameras_from_json(doc, p)
        raise InputError("JSON file is neither an INRIA cameras.json (a list of cameras) nor a "
                         "transforms.json (an object with 'frames')", p)
    raise InputError("unknown camera format; expected a COLMAP cameras/images .bin/.txt, "
                     "cameras.json or transforms.json", p)
