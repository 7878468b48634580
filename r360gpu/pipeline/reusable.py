"""Outputs of the 3D features a user can take elsewhere, written under ``--out`` and listed in results.json.

* the lifted target (``[target]`` or ``--orbit``): ``target/SCENE/target.npy``, the target's rows of
  pre's file as written (int64, ascending; the rows a ``[target] indices`` file takes), and
  ``target/SCENE/target.ply``, pre's file vertex for vertex with a ``target`` property (1: target;
  SuperSplat or r360gpu's viewer can select by it);
* the target masks r360gpu rendered (views without a given mask, every orbit pose):
  ``target/SCENE/masks/VIEW.png`` and ``orbit/SCENE/masks/VIEW.png`` (8-bit gray, 255 = target);
* the orbit's kept poses as an INRIA ``cameras.json`` (``orbit/SCENE/cameras.json``), in the bundle's
  cameras' world (the world the evaluation cameras are given in): a method given as renderings can be
  rendered there by its own renderer.

Every file is written atomically; the entries give paths relative to the output folder.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..bundle.model import ORBIT_CAMERAS
from ..io.cameras_json import save_cameras_json
from ..io.inria_ply import TARGET, write_labelled_ply
from ..util.atomic import atomic_open, write_bytes

TARGET_DIR = "target"
ORBIT_DIR = "orbit"


def _masks(out: Path, folder: Path, masks: dict) -> dict:
    """{view: relative path} of ``masks`` {view: (H, W) bool} written as PNGs under ``out/folder/masks``."""
    from ..report.png import encode

    paths = {}
    for v, m in masks.items():
        rel = folder / "masks" / f"{v}.png"
        write_bytes(out / rel, encode(np.where(np.asarray(m, bool), 255, 0).astype(np.uint8)))
        paths[v] = str(rel)
    return paths


def write_target(out, scene: str, gaussians, target: np.ndarray, masks: dict, *, source=None) -> dict:
    """{"indices", "ply", "masks": {view: path}} of the lifted ``target`` (N,) bool over pre's
    ``gaussians`` (read from ``source``) and the rendered ``masks`` {view: (H, W) bool}, written under
    ``out/target/SCENE``."""
    out, folder = Path(out), Path(TARGET_DIR) / scene
    rows = np.sort(gaussians.rows[np.asarray(target, bool)]).astype(np.int64)
    with atomic_open(out / folder / "target.npy", "wb") as f:
        np.save(f, rows)
    write_labelled_ply(out / folder / "target.ply", gaussians, TARGET, np.asarray(target, np.uint8), 0, "u1",
                       source=source)
    return {"indices": str(folder / "target.npy"), "ply": str(folder / "target.ply"),
            "masks": _masks(out, folder, masks)}


def write_orbit(out, scene: str, cameras: list, masks: dict) -> dict:
    """{"cameras", "masks": {view: path}}: the orbit's kept ``cameras`` as ``out/orbit/SCENE/cameras.json``
    and their target ``masks`` {view: (H, W) bool} as PNGs."""
    out, folder = Path(out), Path(ORBIT_DIR) / scene
    save_cameras_json(out / folder / ORBIT_CAMERAS, cameras)
    return {"cameras": str(folder / ORBIT_CAMERAS), "masks": _masks(out, folder, masks)}
