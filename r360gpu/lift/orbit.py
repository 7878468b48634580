"""Cameras all around the target (Remove360 from every side), and which of them to keep.

:func:`orbit_cameras` puts N cameras on a band of the sphere around the
target's centre: the radius is the evaluation cameras' median distance to it,
the elevations span theirs, the azimuths go all the way round (golden-angle
spacing, so any N covers the band evenly; each of the three can be set), a
camera farther out than a capture all around the target went is brought nearer, every camera looks at the centre
with the evaluation cameras' intrinsics (those of the camera with the median
focal length).  "Up" is the normal of the cameras' (level) right axes,
so the band follows the capture's horizon whatever the world's axes (:func:`capture_up`).

:func:`keep_pose` says whether a pose can be scored: not when the camera sits
inside geometry (something covers most of the image at less than
:data:`INSIDE_DEPTH` of the distance to the target) and not when the target
is not seen in pre (its mask over pre holds less than `MIN_VISIBLE` of
the target's own silhouette, or nothing): "never seen" when that side of the
target is mostly Gaussians no evaluation view saw, else "target occluded".
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
#: An orbit camera may sit this share farther out than the capture's farthest camera its way (`_reach`).
BOUNDS_MARGIN = 0.1
#: Horizontal directions checked for a capture all around the target (`capture_reach`).
_SURROUND_DIRECTIONS = 72
#: A target Gaussian was seen by the capture when its compositing weight over the evaluation views
#: (pre rendered there, occluders included) reaches this (pixels' worth of alpha x transmittance).
SEEN_WEIGHT = 0.05
#: The reasons a pose is dropped (`keep_pose`).
INSIDE, NEVER_SEEN, OCCLUDED = "inside geometry", "never seen", "target occluded"
_GOLDEN = np.pi * (3.0 - np.sqrt(5.0))
#: At most this many orbit poses: golden-angle spacing puts 10,000 poses about 2 degrees apart on the
#: sphere, closer than views that differ; more only re-score the same views (and a count like 1e6
#: is a typo that would run for days).
MAX_POSES = 10_000


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


def capture_reach(centre, cameras, up) -> np.ndarray | None:
    """The evaluation cameras' horizontal offsets from ``centre`` (K, 3) when they surround it (for
    every horizontal direction some camera lies beyond the centre: a capture all around, whose
    extent bounds the room), else None: a capture from one side says nothing of the room behind
    the target, and nothing is capped."""
    off = np.array([np.asarray(c.center, np.float64) - centre for c in cameras])
    off = off - np.outer(off @ up, up)
    a = np.cross(up, [1.0, 0, 0]) if abs(up[0]) < 0.9 else np.cross(up, [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    turn = np.linspace(0, 2 * np.pi, _SURROUND_DIRECTIONS, endpoint=False)
    dirs = np.outer(np.cos(turn), a) + np.outer(np.sin(turn), b)
    return off if np.all((off @ dirs.T).max(axis=0) > 0) else None


def _reach(d: np.ndarray, radius: float, up: np.ndarray, offsets) -> float:
    """How far from the centre along unit ``d`` a camera may sit: ``radius``, capped where its
    horizontal distance would pass the capture's farthest camera that way (widened by
    `BOUNDS_MARGIN`; offsets: `capture_reach`, None: not capped)."""
    h = d - (d @ up) * up
    hn = float(np.linalg.norm(h))
    if offsets is None or hn < 1e-9:
        return radius
    u = h / hn
    return float(min(radius, (1 + BOUNDS_MARGIN) * float((offsets @ u).max()) / hn))


def check_pose_count(n, what: str = "orbit (--orbit)", *, low: int = 0) -> None:
    """InputError (naming ``what``) unless ``n`` is a whole number of poses from ``low`` to `MAX_POSES`."""
    from numbers import Integral

    if isinstance(n, bool) or not isinstance(n, Integral) or not low <= n <= MAX_POSES:
        raise InputError(f"{what} must be a whole number of cameras from {low} to {MAX_POSES} (poses about 2 "
                         f"degrees apart), got {n!r}")


def orbit_cameras(centre, cameras, n: int, *, prefix: str = "orbit", radius: float = 1.0, elevation=None,
                  azimuth=(0.0, 360.0)) -> list[Camera]:
    """``n`` cameras around ``centre`` (3,) (see the module docstring), named ``{prefix}_000`` on.

    cameras: the evaluation cameras (`Camera`, at
    least one).  radius: the orbit's radius as a multiple of their median
    distance to ``centre``; elevation: (lo, hi) degrees above the capture's
    horizon (None: the span of the evaluation cameras'); azimuth: (from, to)
    degrees around ``up``, 0 being the first evaluation camera's direction.
    When the capture surrounds the target (`capture_reach`), a camera
    is brought nearer where it would pass the capture's farthest camera its
    way, so poses stay in the room.
    Returns a list of Camera with the median-focal evaluation camera's fx,
    fy, cx, cy, width, height.
    """
    cameras = list(cameras)
    check_pose_count(n, "an orbit", low=1)
    if not cameras:
        raise InputError("an orbit needs the evaluation cameras (distance, elevation and intrinsics)")
    centre = np.asarray(centre, np.float64).reshape(3)
    up = capture_up(cameras)
    offsets = np.array([np.asarray(c.center, np.float64) - centre for c in cameras])
    dist = np.linalg.norm(offsets, axis=1)
    median = float(np.median(dist))
    if not median > 0:
        raise InputError("the evaluation cameras sit at the target's centre; cannot place an orbit")
    radius = median * float(radius)
    if elevation is None:
        elev = np.arcsin(np.clip(offsets @ up / np.maximum(dist, 1e-12), -1, 1))
        lo, hi = float(elev.min()), float(elev.max())
    else:
        lo, hi = (float(np.deg2rad(e)) for e in elevation)
    az0, az_share = float(np.deg2rad(azimuth[0])), (float(azimuth[1]) - float(azimuth[0])) / 360.0
    # Azimuth zero: the first camera's horizontal direction (any fixed choice; the band is closed).
    ref = offsets[0] - (offsets[0] @ up) * up
    if np.linalg.norm(ref) < 1e-9:
        ref = np.cross(up, [1.0, 0, 0]) if abs(up[0]) < 0.9 else np.cross(up, [0, 1.0, 0])
    ex = ref / np.linalg.norm(ref)
    ey = np.cross(up, ex)
    reach = capture_reach(centre, cameras, up)
    model = sorted(cameras, key=lambda c: c.fx)[len(cameras) // 2]
    out = []
    for i in range(n):
        az = az0 + ((i * _GOLDEN) % (2 * np.pi)) * az_share
        frac = (i + 0.5) / n
        el = lo + (hi - lo) * frac
        d = np.cos(el) * (np.cos(az) * ex + np.sin(az) * ey) + np.sin(el) * up
        eye = centre + _reach(d, radius, up, reach) * d
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
              distance: float, seen_share: float | None = None) -> str | None:
    """None when the pose can be scored, else why not: "inside geometry", "never seen" or
    "target occluded".

    pre_alpha, pre_depth: pre rendered there (H, W); mask: the target's mask
    over pre (H, W) bool; silhouette: the target rendered alone, alpha >= 0.5
    (H, W) bool; distance: camera to target centre; seen_share: the share of
    the target's silhouette there made by Gaussians the capture saw
    (`seen_share`; None: not known).  A pose that does not see the
    target is "never seen" when its side of the target is mostly Gaussians no
    evaluation view saw (pre there is unconstrained by the capture, and so is
    what seems to hide it), else "target occluded".
    """
    near = (np.asarray(pre_alpha) >= 0.5) & (np.asarray(pre_depth) > 0) & (pre_depth < INSIDE_DEPTH * distance)
    if near.mean() >= INSIDE_COVER:
        return INSIDE
    sil = int(np.count_nonzero(silhouette))
    if sil == 0 or np.count_nonzero(mask & silhouette) < MIN_VISIBLE * sil:
        return NEVER_SEEN if seen_share is not None and seen_share < MIN_VISIBLE else OCCLUDED
    return None


def seen_share(weights: np.ndarray, seen: np.ndarray) -> float | None:
    """The share of a pose's target silhouette made by Gaussians the capture saw: ``weights`` (K,)
    each target Gaussian's compositing weight rendered alone at the pose, ``seen`` (K,) bool
    (weight over the evaluation views >= `SEEN_WEIGHT`); None when the silhouette is empty."""
    w = np.asarray(weights, np.float64)
    total = float(w.sum())
    return float(w[np.asarray(seen, bool)].sum()) / total if total > 0 else None


def captured(gaussians, target: np.ndarray, cameras, *, ctx=None, options=None, frame=None,
             weights=None) -> np.ndarray:
    """(K,) bool over the K target Gaussians of ``gaussians`` (``target`` (N,) bool): seen by some
    evaluation camera, i.e. compositing weight >= `SEEN_WEIGHT` over ``cameras`` with pre
    rendered there (occluders included), each camera moved into ``frame``.  weights: those (N,)
    weights when already summed (`r360gpu.lift.target.LiftedTarget.w_capture`: the same sums,
    made in the lift's passes); None: rendered here."""
    if weights is not None:
        return np.asarray(weights)[np.asarray(target, bool)] >= SEEN_WEIGHT
    from ..io.frames import in_frame
    from .device import MaskLifter

    lifter = MaskLifter(gaussians, ctx=ctx, options=options)
    try:
        lifter.reset()
        for cam in cameras:
            lifter.add_view(in_frame(frame, cam), np.ones((cam.height, cam.width), np.float32))
        w_in, _ = lifter.weights()
    finally:
        lifter.release()
    return w_in[np.asarray(target, bool)] >= SEEN_WEIGHT
