"""The pinhole camera every camera loader produces and the renderer consumes.

Conventions (defined here, once):

* Extrinsics are **world-to-camera**: ``x_cam = R @ x_world + t`` with ``R``
  (3, 3) float64 a proper rotation and ``t`` (3,) float64.
* Camera axes are **OpenCV's** (= COLMAP's): x right, y down, z forward (the
  viewing direction); a point is in front of the camera when z_cam > 0 and
  z_cam is its depth.
* Intrinsics ``fx, fy, cx, cy`` are in pixels; there is no skew and no
  distortion (distorted source models are rendered as their pinhole part).
* **Pixel coordinates** (u, v) are continuous with the origin at the top-left
  CORNER of the top-left pixel, u to the right and v down: pixel (column i,
  row j) covers [i, i+1) x [j, j+1) and its centre is (i + 0.5, j + 0.5).
  ``cx, cy`` are in these units, so a principal point at the image centre is
  (width / 2, height / 2).  This is COLMAP's convention (centre of the
  top-left pixel at (0.5, 0.5)), nerfstudio's and instant-ngp's (pixel centres
  at +0.5), and INRIA 3DGS's (its rasteriser maps NDC -1..1 to pixel centres
  at integers via ((ndc + 1) * W - 1) / 2, i.e. to corners 0..W here, and it
  assumes cx = W / 2).  OpenCV calibrations put the centre of the top-left
  pixel at (0, 0): add 0.5 to their cx, cy.  A renderer evaluates pixel
  (i, j) at (u, v) = (i + 0.5, j + 0.5).
* Projection: ``u = fx * x_cam / z_cam + cx``, ``v = fy * y_cam / z_cam + cy``.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .rotation import nearest_rotation

# Rotations read from text files carry rounding noise; deviations from
# orthonormality up to this are projected away, larger ones are an error.
ROTATION_TOLERANCE = 1e-4


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64)  # a private copy
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera; see the module docstring for every convention.

    The constructor validates (ValueError): R a proper rotation to 1e-6, all
    values finite, fx, fy > 0, width, height positive integers.
    """

    R: np.ndarray
    t: np.ndarray
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    name: str = ""

    def __post_init__(self) -> None:
        r = _readonly(self.R)
        t = _readonly(self.t).reshape(-1)
        if r.shape != (3, 3) or t.shape != (3,):
            raise ValueError(f"R must be (3, 3) and t (3,), got {r.shape} and {t.shape}")
        if not (np.isfinite(r).all() and np.isfinite(t).all()):
            raise ValueError("R and t must be finite")
        if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.linalg.det(r) <= 0:
            raise ValueError("R is not a proper rotation matrix")
        object.__setattr__(self, "R", r)
        object.__setattr__(self, "t", t)
        for key in ("fx", "fy", "cx", "cy"):
            value = float(getattr(self, key))
            if not np.isfinite(value):
                raise ValueError(f"{key} must be finite, got {value}")
            object.__setattr__(self, key, value)
        if not (self.fx > 0 and self.fy > 0):
            raise ValueError(f"focal lengths must be > 0, got fx={self.fx}, fy={self.fy}")
        for key in ("width", "height"):
            value = getattr(self, key)
            if isinstance(value, bool) or int(value) != value or int(value) <= 0:
                raise ValueError(f"{key} must be a positive integer, got {value!r}")
            object.__setattr__(self, key, int(value))
        object.__setattr__(self, "name", str(self.name))

    @classmethod
    def from_camera_to_world(cls, c2w: np.ndarray, fx: float, fy: float, cx: float, cy: float,
                             width: int, height: int, name: str = "") -> "Camera":
        """Build from a camera-to-world matrix (4x4 or 3x4, OpenCV axes, rigid)."""
        c2w = np.asarray(c2w, dtype=np.float64)
        r_c2w, centre = c2w[:3, :3], c2w[:3, 3]
        r = r_c2w.T
        return cls(r, -r @ centre, fx, fy, cx, cy, width, height, name)

    def key(self) -> tuple:
        """Hashable identity of everything that decides a rendering: pose, intrinsics, size (not the name)."""
        return (self.R.tobytes(), self.t.tobytes(), self.fx, self.fy, self.cx, self.cy, self.width, self.height)

    @property
    def center(self) -> np.ndarray:
        """(3,) float64 camera centre in world coordinates, ``-R.T @ t``."""
        return -self.R.T @ self.t

    @property
    def world_to_camera(self) -> np.ndarray:
        """(4, 4) float64 homogeneous world-to-camera matrix ``[[R, t], [0, 1]]``."""
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R, self.t
        return m

    @property
    def camera_to_world(self) -> np.ndarray:
        """(4, 4) float64 inverse of `world_to_camera` (OpenCV camera axes)."""
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R.T, self.center
        return m

    @property
    def K(self) -> np.ndarray:
        """(3, 3) float64 intrinsic matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points to pixels.

        points_world: (N, 3).  Returns ``(pixels, depth)``: pixels (N, 2)
        float64 (u, v) in the corner-origin convention of the module docstring,
        NaN for points with depth <= 0 (behind or on the camera plane); depth
        (N,) float64, the camera-space z.
        """
        p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
        cam = p @ self.R.T + self.t
        z = cam[:, 2]
        in_front = z > 0
        safe_z = np.where(in_front, z, 1.0)
        uv = np.stack([self.fx * cam[:, 0] / safe_z + self.cx,
                       self.fy * cam[:, 1] / safe_z + self.cy], axis=1)
        uv[~in_front] = np.nan
        return uv, z

    def resized(self, width: int, height: int) -> "Camera":
        """The same camera rendering an image of ``width x height`` pixels (intrinsics scaled;
        exact in the corner-origin pixel convention)."""
        sx, sy = width / self.width, height / self.height
        return Camera(self.R, self.t, self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy,
                      width, height, self.name)

    def __repr__(self) -> str:
        return (f"Camera(name={self.name!r}, {self.width}x{self.height}, fx={self.fx:.6g}, "
                f"fy={self.fy:.6g}, cx={self.cx:.6g}, cy={self.cy:.6g}, "
                f"center={np.array2string(self.center, precision=4)})")


def checked_rotation(m, path: str | os.PathLike, what: str) -> np.ndarray:
    """A 3x3 rotation read from a file: projected onto SO(3) when off by at most
    :data:`ROTATION_TOLERANCE`, else InputError (scale, shear or reflection)."""
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise InputError(f"{what}: rotation must be a finite 3x3 matrix", path)
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: err is inf (or nan), refused below
        err = float(np.abs(m.T @ m - np.eye(3)).max())
        det = float(np.linalg.det(m))
    if not err <= ROTATION_TOLERANCE or not det > 0:
        raise InputError(f"{what}: not a rotation matrix (max |R^T R - I| = {err:.3g}, det = {det:.4g})", path)
    return nearest_rotation(m)


def make_camera(path: str | os.PathLike, R, t, fx, fy, cx, cy, width, height, name: str) -> Camera:
    """:class:`Camera` from file values; invalid values become an InputError naming the
    file and the camera."""
    try:
        return Camera(R, t, fx, fy, cx, cy, width, height, name)
    except (ValueError, TypeError) as e:
        raise InputError(f"camera {name!r}: {e}", path) from None
