"""The synthetic scene: background, target, cameras, and what the target hides.

A :class:`SyntheticScene` is a complete world: the background includes the
surfaces the target stands on or in front of, so removing the target's
Gaussians leaves exactly the scene a capture *without* the object would
reconstruct (the reference).  The part of the background that no camera of
the scene ever sees because the target is in the way is marked ``hidden``:
a removal method that does not complete the scene lacks it (the ``hole``
method).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..io import Camera, Gaussians
from ..render import NEAR_PLANE
from .cameras import Rig, orbit_cameras
from .primitives import Part, Solid, assemble


@dataclass(frozen=True, eq=False)
class SyntheticScene:
    """One synthetic scene (metres, world z up; see :mod:`r360gpu.synthetic.primitives`).

    background: every Gaussian but the target's, hidden ones included (the
        reference scene).
    target: the object to remove.
    pre: background then target (the original reconstruction); Gaussian
        ``i < background.n`` of pre is background Gaussian ``i``.
    part_index: (N_bg,) int32 index into part_names of each background Gaussian.
    shell: (N_bg,) bool, structural surfaces (floor, walls, ground, sky).
    hidden: (N_bg,) bool, background no camera sees because the target blocks
        it in every view that frames it (and blocks it in at least one).
    solids: box volumes of the target (the occluding shape).
    neighbourhood: the box around the target that the over-eager removal
        (``over_removal``) clears of everything but the shell.
    cameras: evaluation cameras (OpenCV, see :mod:`r360gpu.io.camera`).
    view_kinds: camera name -> "object" | "edge" | "away" (see
        :mod:`r360gpu.synthetic.cameras`).
    """

    name: str
    prompt: str
    background: Gaussians
    target: Gaussians
    pre: Gaussians
    part_index: np.ndarray
    part_names: tuple
    shell: np.ndarray
    hidden: np.ndarray
    solids: tuple
    neighbourhood: Solid
    cameras: tuple
    view_kinds: dict = field(default_factory=dict)

    def in_neighbourhood(self) -> np.ndarray:
        """(N_bg,) bool: background Gaussians inside :attr:`neighbourhood` that are not shell."""
        inside = self.neighbourhood.contains(np.asarray(self.background.means, np.float64))
        return inside & ~self.shell


def hidden_background(means: np.ndarray, solids: Sequence[Solid], cameras: Sequence[Camera]) -> np.ndarray:
    """(N,) bool: points (N, 3) that the solids block in every camera framing them
    and in at least one (a point is framed when it projects into the image in front
    of the near plane)."""
    pts = np.asarray(means, np.float64)
    seen = np.zeros(len(pts), bool)
    blocked_once = np.zeros(len(pts), bool)
    for cam in cameras:
        uv, z = cam.project(pts)
        with np.errstate(invalid="ignore"):
            framed = ((z > NEAR_PLANE) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width)
                      & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height))
        idx = np.flatnonzero(framed)
        blocked = np.zeros(len(idx), bool)
        for solid in solids:
            blocked |= solid.blocks(cam.center, pts[idx])
        seen[idx[~blocked]] = True
        blocked_once[idx[blocked]] = True
    return blocked_once & ~seen


def build_scene(name: str, prompt: str, background: Sequence[Part], target: Sequence[Part],
                solids: Sequence[Solid], neighbourhood: Solid, rig: Rig, *, n_views: int, width: int,
                height: int, rng: np.random.Generator) -> SyntheticScene:
    """Assemble the parts, place the cameras and find the hidden background."""
    bg, index = assemble(background)
    tg, _ = assemble(target)
    names = tuple(p.name for p in background)
    # Parts with the same name (e.g. several "plant" pieces) share one name index.
    unique = tuple(dict.fromkeys(names))
    index = np.array([unique.index(names[i]) for i in range(len(names))], np.int32)[index]
    shell = np.concatenate([np.full(p.n, p.shell) for p in background])
    cameras, kinds = orbit_cameras(rig, n_views, width, height, rng)
    hidden = hidden_background(bg.means, solids, cameras)
    return SyntheticScene(
        name=name, prompt=prompt, background=bg, target=tg, pre=Gaussians.concat([bg, tg]),
        part_index=index, part_names=unique, shell=shell, hidden=hidden, solids=tuple(solids),
        neighbourhood=neighbourhood, cameras=tuple(cameras), view_kinds=kinds,
    )
