"""Cameras all around the target (Remove360 from every side), and which of them to keep.

:func:`orbit_cameras` puts N cameras on a band of the sphere around the
target's centre: the radius is the evaluation cameras' median distance to it,
the elevations span theirs, the azimuths go all the way round (golden-angle
spacing, so any N covers the band evenly), every camera looks at the centre
with the evaluation cameras' intrinsics (those of the camera with the median
focal length).  "Up" is the normal of the cameras' (level) right axes,
so the band follows the capture's horizon whatever the world's axes (:func:`capture_up`).

:func:`keep_pose` says whether a pose can be scored: not when the camera sits
inside geometry (something covers most of the image at less than
:data:`INSIDE_DEPTH` of the distance to the target) and not when the target
is occluded in pre (its mask over pre holds less than :data:`MIN_VISIBLE` of
the target's own silhouette, or nothing).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..io.camera import Camera

#: A pose is inside geometry when pre covers most of its image nearer than this fraction of the target distance.
INSIDE_DEPTH = 0.25
#: ...and "most" means this fraction of the pixels.
INSIDE_COVER = 0.5
#: A pose sees the target when its mask over pre keeps at least this share of the target's own silhouette.
MIN_VISIBLE = 0.5
_GOLDEN = np.pi * (3.0 - np.sqrt(5.0))


def capture_up(cameras) -> np.ndarray:
    """(3,) unit vector: the capture's "up".

    Captures hold the camera level (no roll), so every camera's right axis
    (OpenCV x) is horizontal: up is the normal of the plane the right axes
    span, on the side of the cameras' mean -y.  When they span no plane (a
    narrow arc), the mean -y with its component along the right axis removed.
    """
    R = np.array([np.asarray(c.R, np.float64) for c in cameras])
    rights, ups = R[:, 0], -R[:, 1]
    mean_up = ups.mean(axis=0)
    _, sv, vt = np.linalg.svd(rights, full_matrices=True)
    if len(rights) >= 2 and sv[1] > 0.1 * sv[0]:
        up = vt[2]
    else:
        r = rights.mean(axis=0)
        r /= max(np.linalg.norm(r), 1e-12)
        up = mean_up - (mean_up @ r) * r
    if up @ mean_up < 0:
        up = -up
    norm = np.linalg.norm(up)
    if not norm > 1e-6:
        raise InputError("the evaluation cameras have no common up direction; cannot place an orbit")
    return up / norm


def orbit_cameras(centre, cameras, n: int, *, prefix: str = "orbit") -> list[Camera]:
    """``n`` cameras around ``centre`` (3,) (see the module docstring), named ``{prefix}_000`` on.

    cameras: the evaluation cameras (`Camera`, at
    least one).  Returns a list of Camera with the median-focal evaluation
    camera's fx, fy, cx, cy, width, height.
    """
    cameras = list(cameras)
    if n < 1:
        raise InputError(f"an orbit needs at least 1 camera, got {n}")
    if not cameras:
        raise InputError("an orbit needs the evaluation cameras (distance, elevation and intrinsics)")
    centre = np.asarray(centre, np.float64).reshape(3)
    up = capture_up(cameras)
    offsets = np.array([np.asarray(c.center, np.float64) - centre for c in cameras])
    dist = np.linalg.norm(offsets, axis=1)
    radius = float(np.median(dist))
    if not radius > 0:
        raise InputError("the evaluation cameras sit at the target's centre; cannot place an orbit")
    elev = np.arcsin(np.clip(offsets @ up / np.maximum(dist, 1e-12), -1, 1))
    lo, hi = float(elev.min()), float(elev.max())
    # Azimuth zero: the first camera's horizontal direction (any fixed choice; the band is closed).
    ref = offsets[0] - (offsets[0] @ up) * up
    if np.linalg.norm(ref) < 1e-9:
        ref = np.cross(up, [1.0, 0, 0]) if abs(up[0]) < 0.9 else np.cross(up, [0, 1.0, 0])
    ex = ref / np.linalg.norm(ref)
    ey = np.cross(up, ex)
    model = sorted(cameras, key=lambda c: c.fx)[len(cameras) // 2]
    out = []
    for i in range(n):
        az = (i * _GOLDEN) % (2 * np.pi)
        frac = (i + 0.5) / n
        el = lo + (hi - lo) * frac
        d = np.cos(el) * (np.cos(az) * ex + np.sin(az) * ey) + np.sin(el) * up
        eye = centre + radius * d
        fwd = -d
        right = np.cross(fwd, up)
        if np.linalg.norm(right) < 1e-9:  # looking straight along up: any right will do
            right = ex
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([right, down, fwd], 1)
        c2w[:3, 3] = eye
        out.append(Camera.from_camera_to_world(c2w, model.fx, model.fy, model.cx, model.cy, model.width,
                                               model.height, f"{prefix}_{i:03d}"))
    return out


def keep_pose(pre_alpha: np.ndarray, pre_depth: np.ndarray, mask: np.ndarray, silhouette: np.ndarray,
              distance: float) -> str | None:
    """None when the pose can be scored, else why not: "inside geometry" or "target occluded".

    pre_alpha, pre_depth: pre rendered there (H, W); mask: the target's mask
    over pre (H, W) bool; silhouette: the target rendered alone, alpha >= 0.5
    (H, W) bool; distance: camera to target centre.
    """
    near = (np.asarray(pre_alpha) >= 0.5) & (np.asarray(pre_depth) > 0) & (pre_depth < INSIDE_DEPTH * distance)
    if near.mean() >= INSIDE_COVER:
        return "inside geometry"
    sil = int(np.count_nonzero(silhouette))
    if sil == 0 or np.count_nonzero(mask & silhouette) < MIN_VISIBLE * sil:
        return "target occluded"
    return None
