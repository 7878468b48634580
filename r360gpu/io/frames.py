"""World frames: the cameras moved into the frame a trainer left its splats in.

Trainers move the world before they train, and export the Gaussians in the
moved frame, so their PLY does not line up with the cameras they were trained
from:

* **nerfstudio** (splatfacto) orients, centres and scales the poses of its
  ``transforms.json`` and writes what it did to ``dataparser_transforms.json``
  (``transform``, 3x4, and ``scale``); ``ns-export gaussian-splat`` writes the
  Gaussians in that frame.  The file maps nerfstudio's *original* data
  coordinates (the COLMAP world) to its frame: ``x_ns = scale * (T @ x)``,
  where ``T`` already includes the ``applied_transform`` that ``ns-process-data``
  applied when it wrote ``transforms.json`` (COLMAP world -> transforms.json
  world).  So with COLMAP or INRIA ``cameras.json`` cameras the file is used
  as it is, and with ``transforms.json`` cameras its ``applied_transform``
  (and ``applied_scale``) is taken back out first:
  ``x_ns = (scale / applied_scale) * (T @ A^-1 @ x)``.  A ``transforms.json``
  without ``applied_transform`` next to a ``colmap/sparse/0`` folder gets the
  matrix nerfstudio assumes for such legacy folders
  ``[[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, -1, 0]]``, as its dataparser does.
* **gsplat**'s ``simple_trainer`` (``normalize_world_space=True``, the
  default) normalises the world of its COLMAP model before training and
  saves PLYs (``save_ply``) in it: a similarity from the cameras (up axis
  from the mean camera up, centre at the median of the points nearest to the
  origin on the optical axes, scale 1 / median camera distance), then a
  rotation onto the principal axes of the COLMAP sparse points, then (gsplat
  1.5.2 and later) a 180 degree turn about x when the points' median height
  is above their mean ("up side down").  r360gpu recomputes it from the
  COLMAP model (every camera of ``images.bin`` and every point of
  ``points3D.bin``): :func:`gsplat_frame`.

A :class:`Frame` is the similarity ``x_splats = s * R @ x_cameras + t``.  It is
applied to the cameras, never to the Gaussians: a rotated Gaussian would need
its spherical-harmonics coefficients rotated too, while a moved camera sees
the trained Gaussians exactly as the trainer did.  Intrinsics are unchanged.

Depth: a camera in the splats' frame measures depth in the splats' units,
``s`` times the cameras' units.  A framed source divides its rendered depth
by ``s`` (:class:`r360gpu.render.sources.SceneSource`), so every source of a
bundle gives depth in the units of the bundle's cameras, whatever frame each
was trained in, and depth comparisons between sources stay consistent.

One place applies a frame: `in_frame` (a camera), `depth_in_cameras`
(a depth image) and `points_in_cameras` (points of the splats' frame back
in the cameras' world).  Every consumer of a splat source's cameras --
rendering, lifting a target, target masks, orbit poses, residuals, pruning,
the viewer -- goes through them, with ``frame=None`` (the cameras' own frame)
costing nothing.  What is placed in the world (the target's centre, the
orbit poses) is in the cameras' world; what belongs to one file (a residual
PLY, a ``[target]`` box or indices over pre) is in that file's coordinates.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .camera import ROTATION_TOLERANCE, Camera
from .jsonfile import read_json

#: The file nerfstudio writes next to a run's config.yml, looked for beside an exported scene.
DATAPARSER_TRANSFORMS = "dataparser_transforms.json"
#: Values of a ``frame`` key other than a file path.
FRAME_KEYWORDS = ("auto", "cameras", "gsplat", "gsplat-noflip")
#: nerfstudio's applied_transform for COLMAP-converted folders written before it recorded one.
_LEGACY_APPLIED = ((0.0, 1.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, -1.0, 0.0))


@dataclass(frozen=True)
class Frame:
    """A similarity ``x_splats = M[:3, :3] @ x + M[:3, 3]`` with ``M[:3, :3] = scale * rotation``.

    matrix: the 4x4 matrix as nested tuples (so a frame is hashable and part of a
    source's identity); origin: where it came from, in words.  Build it with
    :meth:`from_matrix`, which checks that it is a similarity.
    """

    matrix: tuple
    origin: str

    @classmethod
    def from_matrix(cls, m, origin: str, path: str | os.PathLike | None = None) -> "Frame":
        """A frame from a 4x4 (or 3x4) similarity; InputError (naming ``path``) when it is not one:
        a positive uniform scale times a proper rotation, to :data:`ROTATION_TOLERANCE`."""
        m = np.asarray(m, dtype=np.float64)
        if m.shape not in ((3, 4), (4, 4)) or not np.isfinite(m).all():
            raise InputError(f"{origin}: a frame is a finite 3x4 or 4x4 matrix, got shape {m.shape}", path)
        full = np.eye(4)
        full[:3, :] = m[:3, :]
        a = full[:3, :3]
        det = np.linalg.det(a)
        if det <= 0:
            raise InputError(f"{origin}: the transform reflects or collapses the world (det {det:.4g}); "
                             f"cameras can follow a rotation, a uniform scale and a shift only", path)
        s = float(np.cbrt(det))
        r = a / s
        err = float(np.abs(r.T @ r - np.eye(3)).max())
        if err > ROTATION_TOLERANCE:
            raise InputError(f"{origin}: the transform is not a rotation times a uniform scale "
                             f"(max |R^T R - I| = {err:.3g})", path)
        u, _, vt = np.linalg.svd(r)  # rounding noise of a stored matrix projected away
        full[:3, :3] = s * (u @ vt)
        return cls(tuple(tuple(float(v) for v in row) for row in full), origin)

    @property
    def m(self) -> np.ndarray:
        """(4, 4) float64 matrix."""
        return np.array(self.matrix, dtype=np.float64)

    @property
    def scale(self) -> float:
        """The similarity's scale ``s`` (splat units per camera unit)."""
        return float(np.cbrt(np.linalg.det(self.m[:3, :3])))

    @property
    def rotation(self) -> np.ndarray:
        return self.m[:3, :3] / self.scale

    @property
    def translation(self) -> np.ndarray:
        return self.m[:3, 3]

    def then(self, other: "Frame", origin: str | None = None) -> "Frame":
        """This frame followed by ``other``."""
        return Frame.from_matrix(other.m @ self.m, origin or f"{self.origin}, then {other.origin}")

    def points(self, xyz) -> np.ndarray:
        """(N, 3) world points moved into the frame."""
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        return xyz @ self.m[:3, :3].T + self.translation

    def points_back(self, xyz) -> np.ndarray:
        """(N, 3) points of the frame (e.g. Gaussian centres) in the cameras' world: `points` undone."""
        xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        return ((xyz - self.translation) @ self.rotation) / self.scale

    def camera(self, cam: Camera) -> Camera:
        """``cam`` moved into the frame: the same image of the moved world (intrinsics kept)."""
        r = self.rotation
        c2w = np.eye(4)
        c2w[:3, :3] = r @ cam.R.T
        c2w[:3, 3] = self.scale * (r @ cam.center) + self.translation
        return Camera.from_camera_to_world(c2w, cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height, cam.name)

    def describe(self) -> dict:
        return {"origin": self.origin, "scale": self.scale, "matrix": [list(row) for row in self.matrix]}


def in_frame(frame: Frame | None, camera: Camera) -> Camera:
    """``camera`` (the bundle's, in the cameras' world) as a source in ``frame`` sees it; the camera
    itself when ``frame`` is None (the source is in the cameras' frame: no work)."""
    return camera if frame is None else frame.camera(camera)


def points_in_cameras(frame: Frame | None, xyz):
    """(N, 3) points of a source in ``frame`` (e.g. its Gaussians' centres) in the cameras' world
    (`Frame.points_back`); ``xyz`` itself when ``frame`` is None."""
    return xyz if frame is None else frame.points_back(xyz)


def depth_in_cameras(frame: Frame | None, depth):
    """A depth image rendered at `in_frame`'s camera, in the cameras' units (divided by the
    frame's scale; 0 stays 0); ``depth`` itself when there is no frame or its scale is 1."""
    if frame is None or depth is None or frame.scale == 1.0:
        return depth
    return depth / np.float32(frame.scale)


# --- nerfstudio ------------------------------------------------------------------------------------

def find_dataparser_transforms(scene: str | os.PathLike) -> Path | None:
    """``dataparser_transforms.json`` beside an exported scene (in its folder; for a folder, inside it)."""
    p = Path(scene)
    folder = p if p.is_dir() else p.parent
    f = folder / DATAPARSER_TRANSFORMS
    return f if f.is_file() else None


def nerfstudio_frame(dataparser_transforms: str | os.PathLike, cameras: str | os.PathLike | None) -> Frame:
    """The frame of a nerfstudio export, for the cameras at ``cameras`` (see the module docstring)."""
    path = Path(dataparser_transforms)
    doc = read_json(path)
    if not isinstance(doc, dict) or "transform" not in doc or "scale" not in doc:
        raise InputError("not a nerfstudio dataparser_transforms.json: expected an object with 'transform' "
                         "(3x4) and 'scale'", path)
    t = _matrix(doc["transform"], "'transform'", path)
    scale = _positive(doc["scale"], "'scale'", path)
    origin = f"nerfstudio {path}"
    kind, cam_file = _camera_source(cameras) if cameras is not None else ("colmap", None)
    if kind == "transforms":
        meta = read_json(cam_file)
        applied = meta.get("applied_transform")
        if applied is None and (cam_file.parent / "colmap" / "sparse" / "0").is_dir():
            applied = _LEGACY_APPLIED
        if applied is not None:
            a = _matrix(applied, f"'applied_transform' of {cam_file}", cam_file)
            t = t @ np.linalg.inv(a)
        if "applied_scale" in meta:
            scale /= _positive(meta["applied_scale"], f"'applied_scale' of {cam_file}", cam_file)
        origin += f" (for the transforms.json cameras {cam_file})"
    m = np.diag([scale, scale, scale, 1.0]) @ t
    return Frame.from_matrix(m, origin, path)


def _matrix(value, what: str, path) -> np.ndarray:
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{what} is not a numeric matrix", path) from None
    if m.shape not in ((3, 4), (4, 4)) or not np.isfinite(m).all():
        raise InputError(f"{what} must be a finite 3x4 or 4x4 matrix, got shape {m.shape}", path)
    full = np.eye(4)
    full[:3, :] = m[:3, :]
    return full


def _positive(value, what: str, path) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise InputError(f"{what} must be a positive number, got {value!r}", path)
    return float(value)


def _camera_source(cameras: str | os.PathLike) -> tuple[str, Path]:
    """("colmap", model folder) | ("transforms", file) | ("cameras.json", file) for a ``cameras`` path,
    as :func:`r360gpu.io.load.load_cameras` reads it."""
    p = Path(cameras)
    if p.is_dir():
        for d in (p, p / "sparse" / "0", p / "sparse"):
            if any((d / f"cameras{e}").is_file() and (d / f"images{e}").is_file() for e in (".bin", ".txt")):
                return "colmap", d
        for name, kind in (("transforms.json", "transforms"), ("cameras.json", "cameras.json")):
            if (p / name).is_file():
                return kind, p / name
        return "unknown", p
    if p.suffix.lower() in (".bin", ".txt"):
        return "colmap", p.parent
    if p.suffix.lower() == ".json":
        from .transforms_json import is_transforms_json

        return ("transforms" if is_transforms_json(read_json(p)) else "cameras.json"), p
    return "unknown", p


# --- gsplat ----------------------------------------------------------------------------------------

def gsplat_frame(cameras: str | os.PathLike, *, flip: bool = True) -> Frame:
    """gsplat ``simple_trainer``'s world normalisation of the COLMAP model at ``cameras``.

    flip: apply gsplat's "up side down" turn (gsplat 1.5.2 and later); False
    gives the frame of earlier versions.  The model must be the one gsplat
    trained on, with every camera and its ``points3D``.
    """
    from .colmap import load_colmap
    from .colmap_points import points3d_file, read_points3d

    kind, folder = _camera_source(cameras)
    if kind != "colmap":
        raise InputError("gsplat's normalisation is recomputed from the COLMAP model gsplat trained on "
                         "(cameras, images and points3D .bin/.txt); cameras must name that model", cameras)
    points_file = points3d_file(folder)
    if points_file is None:
        raise InputError("gsplat's normalisation aligns the world to the COLMAP sparse points: no points3D.bin or "
                         "points3D.txt beside the cameras", folder)
    points = read_points3d(points_file).astype(np.float32)  # gsplat's parser keeps them as float32
    if len(points) < 4:
        raise InputError(f"gsplat's normalisation needs the COLMAP sparse points; {points_file.name} has "
                         f"{len(points)}", points_file)
    cams = sorted(load_colmap(folder), key=lambda c: c.name)
    what = "gsplat normalize_world_space" + ("" if flip else " (before 1.5.2: no up-side-down turn)")
    return gsplat_normalization(cams, points, flip=flip,
                                origin=f"{what} of {folder} ({len(cams)} cameras, {len(points)} points)",
                                path=folder)


def gsplat_normalization(cameras: list[Camera], points: np.ndarray, *, flip: bool = True,
                         origin: str = "gsplat normalize_world_space", path=None) -> Frame:
    """The frame gsplat's COLMAP parser normalises to, from ``cameras`` and sparse ``points`` (N, 3)."""
    first = _camera_similarity(cameras, origin, path)
    moved = first.points(points)
    frame = first.then(_principal_axes(moved, origin, path), origin)
    if flip:
        moved = frame.points(points)
        if np.median(moved[:, 2]) > np.mean(moved[:, 2]):
            frame = frame.then(Frame.from_matrix(np.diag([1.0, -1.0, -1.0, 1.0]), "turn about x"), origin)
    return frame


def _camera_similarity(cameras: list[Camera], origin: str, path) -> Frame:
    """gsplat's similarity_from_cameras: the cameras' mean up (their -y axis) rotated onto (0, -1, 0),
    the median of the points nearest to the origin on the optical axes moved to the origin, and
    the median camera distance scaled to 1."""
    rot = np.stack([c.R.T for c in cameras])            # camera-to-world rotations (OpenCV axes)
    centres = np.stack([c.center for c in cameras])
    up = -rot[:, :, 1].mean(axis=0)
    up /= np.linalg.norm(up)
    target = np.array([0.0, -1.0, 0.0])
    cos = float(up @ target)
    if cos <= -1.0:  # gsplat falls back to diag(-1, 1, 1), a mirror no camera can follow
        raise InputError(f"{origin}: the cameras' mean up is exactly +y, where gsplat's normalisation mirrors "
                         f"the world; score this scene with frame = \"cameras\" and a scene exported unnormalised",
                         path)
    v = np.cross(up, target)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    align = np.eye(3) + k + k @ k / (1.0 + cos)          # Rodrigues: the rotation taking up onto target
    fwd = (align @ rot)[:, :, 2]
    c = centres @ align.T
    focus = c - np.sum(fwd * c, axis=1, keepdims=True) * fwd   # nearest point to the origin on each optical axis
    shift = -np.median(focus, axis=0)
    scale = 1.0 / np.median(np.linalg.norm(c + shift, axis=1))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = scale * align, scale * shift
    return Frame.from_matrix(m, origin, path)


def _principal_axes(points: np.ndarray, origin: str, path) -> Frame:
    """A rigid motion putting the points' median at the origin and their principal axes on x, y, z
    (largest variance on x, smallest on z), as gsplat's align_principal_axes."""
    centre = np.median(points, axis=0)
    values, vectors = np.linalg.eigh(np.cov(points - centre, rowvar=False))
    vectors = vectors[:, np.argsort(values)[::-1]]
    if np.linalg.det(vectors) < 0:
        vectors[:, 0] *= -1
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = vectors.T, -vectors.T @ centre
    return Frame.from_matrix(m, origin, path)


# --- the frame a bundle source names --------------------------------------------------------------

def resolve_frame(value: str | None, *, scene: str | os.PathLike, cameras: str | os.PathLike | None,
                  root: str | os.PathLike = ".") -> Frame | None:
    """The frame a scene source's ``frame`` key names (None: the cameras' own frame).

    value: ``"auto"`` (the default, also for None): the ``dataparser_transforms.json``
    beside the scene when there is one, else the cameras' frame; ``"cameras"``:
    the cameras' frame; ``"gsplat"`` / ``"gsplat-noflip"``: :func:`gsplat_frame`;
    anything else: the path (relative to ``root``) of a nerfstudio
    ``dataparser_transforms.json``.
    """
    value = "auto" if value is None else value
    if value == "cameras":
        return None
    if value in ("gsplat", "gsplat-noflip"):
        if cameras is None:
            raise InputError(f"frame = {value!r} is recomputed from the cameras: set cameras = \"...\"")
        return gsplat_frame(cameras, flip=value == "gsplat")
    if value == "auto":
        found = find_dataparser_transforms(scene)
        return None if found is None else nerfstudio_frame(found, cameras)
    path = Path(root) / value
    if not path.is_file():
        raise InputError(f"frame {value!r} is neither one of {', '.join(FRAME_KEYWORDS)} nor a "
                         f"dataparser_transforms.json file", path)
    return nerfstudio_frame(path, cameras)
