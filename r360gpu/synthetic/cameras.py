"""Evaluation cameras of a synthetic scene: an arc of views around the target.

Like a hand-held capture, the cameras walk along an arc around the target at
varying distance and height, aimed at it.  A few views are deliberately
imperfect (their kind is recorded so tests and reports can find them):

* ``"object"``: aimed at the target (a small random aiming error);
* ``"edge"``: turned sideways by half the horizontal field of view, so the
  target straddles the image border (partly out of frame);
* ``"away"``: turned by :data:`AWAY_TURN` from the target, so it is out of
  frame and the view's target mask is empty (the protocol excludes such
  views from the geometric axis).

Views whose line of sight passes an occluder (a plant, a tree) are
``"object"`` views; the scene places the occluder, not this module.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io import Camera

#: How far an "away" view turns from the target (radians).
AWAY_TURN = np.deg2rad(100.0)


@dataclass(frozen=True)
class Rig:
    """Where the cameras of a scene go (metres, radians; world z up).

    target: (3,) point the cameras aim at.  front: azimuth (from +x towards
    +y, seen from the target) of the middle of the arc.  arc: total azimuth
    span.  radius, height: (min, max) horizontal distance from the target and
    camera height.  focal: fx = fy = focal x image width (0.85: a 61 degree
    horizontal field of view).
    """

    target: tuple
    front: float
    arc: float
    radius: tuple
    height: tuple
    focal: float = 0.85


def view_kinds(n_views: int) -> list[str]:
    """The kind of each of ``n_views`` views in order: ~10% "edge" (from 5 views on),
    ~10% "away" (from 4 views on, always the last ones), the rest "object"."""
    n_away = 0 if n_views < 4 else max(1, round(0.1 * n_views))
    n_edge = 0 if n_views < 5 else max(1, round(0.1 * n_views))
    kinds = ["object"] * n_views
    for k in range(n_away):
        kinds[n_views - 1 - k] = "away"
    span = n_views - n_away
    for k in range(n_edge):
        kinds[int((k + 0.35) / n_edge * span)] = "edge"
    return kinds


def synthetic_view_name(i: int) -> str:
    """Name of view ``i`` (camera name = mask file stem)."""
    return f"view_{i:03d}"


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4, 4) camera-to-world matrix in OpenCV axes (x right, y down, z forward) of a
    camera at ``eye`` looking at ``target`` with world ``up`` pointing up in the image."""
    eye, target, up = (np.asarray(a, np.float64) for a in (eye, target, up))
    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    d = np.cross(f, r)
    c2w = np.eye(4)
    c2w[:3, :3] = np.stack([r, d, f], 1)
    c2w[:3, 3] = eye
    return c2w


def _turn(eye, target, angle: float) -> np.ndarray:
    """The look-at point after turning the view direction by ``angle`` about the vertical."""
    d = np.asarray(target, np.float64) - eye
    c, s = np.cos(angle), np.sin(angle)
    return eye + np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]])


def orbit_cameras(rig: Rig, n_views: int, width: int, height: int,
                  rng: np.random.Generator) -> tuple[list[Camera], dict[str, str]]:
    """``n_views`` pinhole cameras along the rig's arc and the kind of each view by name.

    Cameras are named :func:`synthetic_view_name` (``view_000``, ...) in arc order; the
    principal point is the image centre.
    """
    if n_views < 1:
        raise ValueError(f"n_views must be >= 1, got {n_views}")
    target = np.asarray(rig.target, np.float64)
    fx = rig.focal * width
    half_fov = np.arctan(0.5 * width / fx)
    front_vec = np.array([np.cos(rig.front), np.sin(rig.front), 0.0])
    kinds = view_kinds(n_views)
    phase_r, phase_h = rng.uniform(0.0, 2 * np.pi, 2)
    cameras, by_name = [], {}
    for i, kind in enumerate(kinds):
        frac = i / (n_views - 1) if n_views > 1 else 0.5
        azimuth = rig.front + rig.arc * (frac - 0.5)
        wave_r = 0.5 + 0.5 * np.sin(2 * np.pi * 1.3 * frac + phase_r)
        wave_h = 0.5 + 0.5 * np.sin(2 * np.pi * 0.9 * frac + phase_h)
        radius = rig.radius[0] + (rig.radius[1] - rig.radius[0]) * wave_r
        eye = target + np.array([radius * np.cos(azimuth), radius * np.sin(azimuth), 0.0])
        eye[2] = rig.height[0] + (rig.height[1] - rig.height[0]) * wave_h
        aim = target + rng.normal(0.0, 0.04, 3)
        if kind == "edge":
            aim = _turn(eye, aim, half_fov if i % 2 == 0 else -half_fov)
        elif kind == "away":
            # Turn towards the open side of the arc (where the capture came from), not into a wall.
            options = [_turn(eye, aim, a) for a in (AWAY_TURN, -AWAY_TURN)]
            aim = max(options, key=lambda p: float(np.dot(p - eye, front_vec)))
        name = synthetic_view_name(i)
        cameras.append(Camera.from_camera_to_world(look_at(eye, aim), fx, fx, width / 2, height / 2,
                                                   width, height, name))
        by_name[name] = kind
    return cameras, by_name
