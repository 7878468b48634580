"""A trainer's world moves, generated: the similarity transforms a splat export may be in, relative
to the cameras it was trained from (gsplat's normalisation, nerfstudio's dataparser transform, and
random similarities), and the Gaussians moved by one (tests of r360gpu.metrics.frame_check)."""
from __future__ import annotations

import numpy as np

from gsplat_oracle import normalize_world
from r360gpu.io import Gaussians
from r360gpu.io.frames import Frame
from r360gpu.io.rotation import rotmat_to_quat

# ns-process-data's applied_transform (COLMAP world -> transforms.json world)
APPLIED = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 0]])


def moved_gaussians(g: Gaussians, frame: Frame) -> Gaussians:
    """``g`` as a trainer working in ``frame`` holds it (SH degree 0: a rotated world would need
    rotated SH coefficients, which is why r360gpu moves cameras, not Gaussians)."""
    g = g.with_sh_degree(0)
    q = rotmat_to_quat(frame.rotation)
    w1, v1 = q[0], q[1:]
    w2, v2 = g.quats[:, 0].astype(np.float64), g.quats[:, 1:].astype(np.float64)
    quats = np.concatenate([(w1 * w2 - v2 @ v1)[:, None], w1 * v2 + w2[:, None] * v1 + np.cross(v1, v2)], axis=1)
    return Gaussians(frame.points(g.means), g.scales * frame.scale, quats, g.opacities, g.sh)


def rotation(axis, angle: float) -> np.ndarray:
    """The rotation by ``angle`` (radians) about ``axis`` (Rodrigues)."""
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _between(a, b) -> np.ndarray:
    """The rotation turning unit vector ``a`` onto ``b`` (nerfstudio's rotation_matrix_between)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v = np.cross(a, b)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if a @ b > 0 else rotation(np.cross(a, [1.0, 0, 0]) if abs(a[0]) < 0.9 else
                                                     np.cross(a, [0, 1.0, 0]), np.pi)
    return rotation(v, float(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def gsplat_transform(cameras, points, *, flip: bool = True) -> np.ndarray:
    """4x4: gsplat simple_trainer's normalize_world_space, recomputed from the cameras and the
    sparse points (tests/gsplat_oracle.py)."""
    c2w = np.stack([c.camera_to_world for c in sorted(cameras, key=lambda c: c.name)])
    return normalize_world(c2w, np.asarray(points, np.float32), flip=flip)[2]


def nerfstudio_transform(cameras) -> np.ndarray:
    """4x4: COLMAP world -> nerfstudio's dataparser frame as splatfacto's defaults compute it:
    ns-process-data's applied_transform, then auto_orient_and_center_poses (orientation "up": the
    mean camera up turned onto +z; centre "poses": the mean camera position to the origin), then
    auto_scale_poses (the farthest camera coordinate to 1)."""
    a4 = np.eye(4)
    a4[:3] = APPLIED
    c2w = np.stack([a4 @ c.camera_to_world for c in cameras])
    up = -c2w[:, :3, 1].mean(axis=0)  # OpenCV y is down; nerfstudio's (OpenGL) camera y is up
    r = _between(up, np.array([0.0, 0.0, 1.0]))
    orient = np.eye(4)
    orient[:3, :3] = r
    orient[:3, 3] = -r @ c2w[:, :3, 3].mean(axis=0)
    moved = np.einsum("ij,njk->nik", orient, c2w)
    scale = 1.0 / np.abs(moved[:, :3, 3]).max()
    return np.diag([scale, scale, scale, 1.0]) @ orient @ a4


def random_similarity(rng: np.random.Generator, *, centres, radius: float, scales=(0.2, 5.0),
                      any_rotation: bool = False) -> np.ndarray:
    """4x4: a random similarity over a wide range: a rotation by 0-180 degrees about a random axis
    (with ``any_rotation``, uniform over all rotations) and a scale in ``scales`` (log-uniform)
    about one of ``centres`` (the world origin, the object, the cameras' centroid, in turn at
    random), then a shift of up to 1.5 ``radius`` in a random direction."""
    if any_rotation:  # a uniform unit quaternion
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        r = rotation(q[1:], 2.0 * np.arccos(min(1.0, abs(q[0])))) if np.linalg.norm(q[1:]) > 1e-12 else np.eye(3)
    else:
        r = rotation(rng.normal(size=3), rng.uniform(0.0, np.pi))
    s = float(np.exp(rng.uniform(np.log(scales[0]), np.log(scales[1]))))
    c = np.asarray(centres[rng.integers(len(centres))], np.float64)
    shift = rng.normal(size=3)
    shift *= rng.uniform(0.0, 1.5) * radius / np.linalg.norm(shift)
    m = np.eye(4)
    m[:3, :3] = s * r
    m[:3, 3] = c - s * r @ c + shift
    return m
