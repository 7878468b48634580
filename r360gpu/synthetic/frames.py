"""A synthetic bundle moved into another world frame, as a trainer that normalised the world leaves it.

`moved_bundle` copies a bundle, moves every splat file by one
similarity `Frame` (``x' = s R x + t``; the
cameras stay where they are) and declares it as nerfstudio does: a
``dataparser_transforms.json`` (``transform`` = ``[R | t / s]``, ``scale`` =
``s``) named by scene.toml's top-level ``frame``.  The near plane is in scene
units (`RenderOptions`, as a trainer renders
in its own units), so each moved source gets ``near = s * NEAR_PLANE``: the same
Gaussians culled.  Scoring the copy must give what the original gives: the
frame is applied to the cameras, never undone on the Gaussians
(`r360gpu.io.frames`).
"""
from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.frames import DATAPARSER_TRANSFORMS, Frame
from ..io.gaussians import Gaussians
from ..io.rotation import quat_to_rotmat, rotmat_to_quat

#: scene.toml keys naming a splat file.
_SCENE_KEY = 'scene = "'


def moved_gaussians(g: Gaussians, frame: Frame) -> Gaussians:
    """``g`` moved by ``frame``: centres through the similarity, scales times ``s``, rotations
    composed with ``R``.  Degree-0 colour only: a rotated view-dependent colour would need its
    spherical harmonics rotated, which no trainer's export does and this copy does not either."""
    if g.sh_degree != 0:
        raise InputError(f"moving a scene with SH degree {g.sh_degree} needs its SH rotated; degree 0 only")
    r = frame.rotation
    quats = np.array([rotmat_to_quat(r @ m) for m in quat_to_rotmat(g.quats)])
    return Gaussians(frame.points(g.means), np.asarray(g.scales, np.float64) * frame.scale, quats, g.opacities,
                     g.sh)


def random_similarity(rng: np.random.Generator, *, scale=(0.1, 10.0), shift: float = 5.0) -> Frame:
    """A random similarity: a uniform random rotation, a shift in [-shift, shift]^3 and a scale
    log-uniform in ``scale``."""
    q = rng.normal(size=4)
    m = np.eye(4)
    s = float(np.exp(rng.uniform(np.log(scale[0]), np.log(scale[1]))))
    m[:3, :3] = s * quat_to_rotmat(q / np.linalg.norm(q))
    m[:3, 3] = rng.uniform(-shift, shift, 3)
    return Frame.from_matrix(m, "random similarity")


def moved_bundle(src: str | os.PathLike, dst: str | os.PathLike, frame: Frame) -> Path:
    """A copy of the bundle at ``src`` in ``dst`` whose every splat file (``scene = "....ply"``
    of scene.toml) is moved by ``frame`` and whose scene.toml declares it (see the module docstring)."""
    from ..io import load_gaussians
    from ..io.inria_ply import save_ply
    from ..render.conventions import NEAR_PLANE

    src, dst = Path(src), Path(dst)
    text = (src / "scene.toml").read_text()
    if "\nnear =" in text:
        raise InputError("moved_bundle scales the default near plane; this bundle sets its own", src / "scene.toml")
    shutil.copytree(src, dst)
    (dst / "synthetic.json").unlink(missing_ok=True)  # no longer the generator's bytes
    lines = []
    for line in text.splitlines():
        lines.append(line)
        if line.startswith(_SCENE_KEY):
            path = dst / line[len(_SCENE_KEY):].rstrip('"')
            save_ply(path, moved_gaussians(load_gaussians(path), frame))
            lines.append(f"near = {NEAR_PLANE * frame.scale!r}")
    text = "\n".join(lines) + "\n"
    transform = np.eye(4)[:3]
    transform[:, :3] = frame.rotation
    transform[:, 3] = frame.translation / frame.scale
    (dst / DATAPARSER_TRANSFORMS).write_text(json.dumps({"transform": transform.tolist(), "scale": frame.scale}))
    first_table = text.index("\n[")
    (dst / "scene.toml").write_text(f'{text[:first_table]}\nframe = "{DATAPARSER_TRANSFORMS}"{text[first_table:]}')
    return dst
