"""Orbit / fly camera controller: pure numpy, no window or GPU.

Conventions (those of :mod:`r360gpu.io.camera`):

* The pose is the camera-to-world rotation ``C`` (3, 3) float64 whose columns
  are the camera's x (right), y (down) and z (forward) axes in world
  coordinates (OpenCV axes), and the camera centre ``position`` (3,) in world
  units.  The renderer's world-to-camera matrix is ``R = C.T``,
  ``t = -R @ position``.
* ``up`` is the world's up direction (unit (3,)); yaw turns about it, so the
  horizon stays level, and :meth:`CameraController.level` removes any roll.
* ``fov_y`` is the vertical field of view in degrees; rendered images have
  square pixels and the principal point at the image centre, except while the
  camera sits exactly on an evaluation camera (:attr:`snapped`), whose
  intrinsics are used then (scaled to the render size).
* Mouse deltas are in window pixels; ``rotate_speed`` is radians per pixel.
  Orbit: dragging right turns the scene to the right (the camera moves to its
  left around the pivot); dragging down moves the camera up over the pivot.
  Fly (mouse look): dragging right looks right, dragging down looks down.
* Moves (WASD + Q/E) are in world units per second times ``speed`` and the
  modifier factor (Shift x4, Control x0.25, see :data:`SPEED_MODIFIERS`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from r360gpu.io.camera import Camera

#: Speed factors of the modifier keys while moving.
SPEED_MODIFIERS = {"Shift": 4.0, "Control": 0.25}
#: Field-of-view limits in degrees.
FOV_MIN, FOV_MAX = 5.0, 150.0
#: The forward axis never comes closer to +/- up than this (degrees), so yaw stays defined.
PITCH_MARGIN_DEG = 1.0
#: Up-axis choices cycled by :meth:`CameraController.cycle_up` ("auto" = estimated from the cameras).
UP_CHOICES = ("auto", "-y", "+y", "+z", "-z", "+x", "-x")


def rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) float64 rotation by ``angle`` radians about unit ``axis`` (right-handed)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def orthonormalize(c: np.ndarray) -> np.ndarray:
    """The proper rotation nearest to ``c`` (3, 3) (SVD); removes accumulated drift."""
    u, _, vt = np.linalg.svd(np.asarray(c, dtype=np.float64))
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def look_rotation(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Camera-to-world rotation looking along ``forward`` with no roll about world ``up``.

    Columns (right, down, forward): OpenCV's y axis points down, so the down
    column is the part of ``-up`` orthogonal to forward, and right = down x
    forward.  Raises ValueError when ``forward`` is parallel to ``up``.
    """
    f = np.asarray(forward, dtype=np.float64)
    f = f / np.linalg.norm(f)
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    down = -u - np.dot(-u, f) * f
    n = np.linalg.norm(down)
    if n < 1e-9:
        raise ValueError("forward is parallel to the up axis")
    down /= n
    right = np.cross(down, f)
    return np.stack([right, down, f], axis=1)


def up_vector(choice: str, cameras: list[Camera] | None = None) -> np.ndarray:
    """World up for an :data:`UP_CHOICES` entry; "auto" estimates it from ``cameras``."""
    axes = {"x": 0, "y": 1, "z": 2}
    if choice == "auto":
        return estimate_up(cameras or [])
    if len(choice) != 2 or choice[0] not in "+-" or choice[1] not in axes:
        raise ValueError(f"up axis must be one of {UP_CHOICES}, got {choice!r}")
    v = np.zeros(3)
    v[axes[choice[1]]] = 1.0 if choice[0] == "+" else -1.0
    return v


def estimate_up(cameras: list[Camera]) -> np.ndarray:
    """World up as the normalised mean of the cameras' up directions (-y camera axis).

    Captures are taken mostly upright, so the mean camera up is the scene's up
    whatever the reconstruction's world frame.  Without cameras (or when the
    mean vanishes) returns -y, the OpenCV/COLMAP default.
    """
    if cameras:
        ups = np.stack([-c.R[1] for c in cameras])  # row 1 of R = camera y axis in world
        m = ups.sum(axis=0)
        n = np.linalg.norm(m)
        if n > 1e-6 * len(cameras):
            return m / n
    return np.array([0.0, -1.0, 0.0])


def scene_scale(cameras: list[Camera]) -> float:
    """A length for speeds and distances: median distance of the camera centres to their mean (>= 1e-3)."""
    if not cameras:
        return 1.0
    c = np.stack([cam.center for cam in cameras])
    if len(c) == 1:
        return 1.0
    return max(1e-3, float(np.median(np.linalg.norm(c - c.mean(axis=0), axis=1))))


def look_at_point(cameras: list[Camera]) -> np.ndarray | None:
    """The point closest (least squares) to every camera's optical axis, or None.

    In an object-centred capture the cameras all look at the object, so this is
    a good orbit pivot before the target is known.  None with fewer than two
    cameras or (near-)parallel axes.
    """
    if len(cameras) < 2:
        return None
    a = np.zeros((3, 3))
    b = np.zeros(3)
    for cam in cameras:
        d = cam.R[2]  # forward axis in world
        p = np.eye(3) - np.outer(d, d)
        a += p
        b += p @ cam.center
    if np.linalg.cond(a) > 1e6:
        return None
    return np.linalg.solve(a, b)


def fov_of(camera: Camera) -> float:
    """Vertical field of view of ``camera`` in degrees."""
    return math.degrees(2.0 * math.atan(camera.height / (2.0 * camera.fy)))


def view_distance(a_pos, a_rot, b_pos, b_rot, scale: float) -> float:
    """Dissimilarity of two poses: centre distance / ``scale`` + (1 - cos) of the forward axes."""
    d = float(np.linalg.norm(np.asarray(a_pos) - np.asarray(b_pos))) / scale
    cos = float(np.dot(np.asarray(a_rot)[:, 2], np.asarray(b_rot)[:, 2]))
    return d + (1.0 - cos)


def nearest_camera(position, rotation, cameras: list[Camera], scale: float) -> int | None:
    """Index of the camera of ``cameras`` closest to the pose (:func:`view_distance`), None if empty."""
    if not cameras:
        return None
    costs = [view_distance(position, rotation, c.center, c.R.T, scale) for c in cameras]
    return int(np.argmin(costs))


def interpolate(a: Camera, b: Camera, s: float, width: int | None = None, height: int | None = None) -> Camera:
    """The camera a fraction ``s`` in [0, 1] of the way from ``a`` to ``b``.

    Centres are interpolated linearly, rotations along the shortest arc
    (slerp of the relative rotation), the vertical field of view linearly;
    the result renders ``width x height`` (default: ``a``'s size) with a
    centred principal point.
    """
    s = float(min(1.0, max(0.0, s)))
    ca, cb = a.R.T, b.R.T
    rel = ca.T @ cb
    angle = math.acos(max(-1.0, min(1.0, (np.trace(rel) - 1.0) / 2.0)))
    if angle < 1e-9:
        c = ca
    else:
        axis = np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
        n = np.linalg.norm(axis)
        if n < 1e-9:  # 180 degrees: any axis orthogonal to both works; use the eigenvector of +1
            w, v = np.linalg.eigh(rel + rel.T)
            axis = v[:, np.argmax(w)]
        else:
            axis = axis / n
        c = ca @ rotation_about(axis, s * angle)
    pos = (1.0 - s) * a.center + s * b.center
    fov = (1.0 - s) * fov_of(a) + s * fov_of(b)
    w = int(width or a.width)
    h = int(height or a.height)
    return pinhole(c, pos, fov, w, h, name=f"{a.name}>{b.name}@{s:.3f}")


def pinhole(rotation: np.ndarray, position: np.ndarray, fov_y: float, width: int, height: int, name: str = "") -> Camera:
    """A :class:`Camera` at ``position`` with camera-to-world ``rotation``, square pixels,
    centred principal point and vertical field of view ``fov_y`` degrees."""
    fy = (height / 2.0) / math.tan(math.radians(fov_y) / 2.0)
    r = orthonormalize(rotation).T
    return Camera(r, -r @ np.asarray(position, dtype=np.float64), fy, fy, width / 2.0, height / 2.0,
                  int(width), int(height), name)


@dataclass
class CameraController:
    """The viewer's camera: pose, field of view, orbit pivot, mode and world up.

    Every method changes the pose in place and returns nothing; all of it is
    deterministic numpy (tests drive it without a window).
    """

    position: np.ndarray
    rotation: np.ndarray  # camera-to-world (3, 3), columns right, down, forward
    fov_y: float = 60.0
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, -1.0, 0.0]))
    up_choice: str = "auto"
    mode: str = "orbit"  # "orbit" | "fly"
    speed: float = 1.0  # world units per second for WASD / QE
    rotate_speed: float = 0.005  # radians per pixel
    snapped: Camera | None = None  # the evaluation camera the pose equals, if any
    home: tuple | None = None  # (position, rotation, fov_y, pivot) restored by reset()

    # -- construction -------------------------------------------------------
    @classmethod
    def for_cameras(cls, cameras: list[Camera], *, start: int = 0, pivot: np.ndarray | None = None) -> "CameraController":
        """A controller on ``cameras[start]`` with up, speed and pivot derived from ``cameras``.

        Without cameras: at (0, 0, -3 scale) looking at the origin with -y up.
        """
        up = estimate_up(cameras)
        scale = scene_scale(cameras)
        if pivot is None:
            pivot = look_at_point(cameras)
        if cameras:
            cam = cameras[start]
            ctl = cls(position=cam.center.copy(), rotation=cam.R.T.copy(), fov_y=fov_of(cam), up=up,
                      speed=scale * 0.5)
            if pivot is None:
                pivot = cam.center + cam.R[2] * scale
            ctl.pivot = np.asarray(pivot, dtype=np.float64).copy()
            ctl.snapped = cam
        else:
            pos = np.array([0.0, 0.0, -3.0])
            ctl = cls(position=pos, rotation=look_rotation(-pos, up), up=up, speed=scale * 0.5,
                      pivot=np.zeros(3))
        ctl.home = (ctl.position.copy(), ctl.rotation.copy(), ctl.fov_y, ctl.pivot.copy())
        return ctl

    # -- derived ------------------------------------------------------------
    @property
    def forward(self) -> np.ndarray:
        return self.rotation[:, 2].copy()

    @property
    def right(self) -> np.ndarray:
        return self.rotation[:, 0].copy()

    @property
    def down(self) -> np.ndarray:
        return self.rotation[:, 1].copy()

    def pose_key(self) -> tuple:
        """A hashable key that changes whenever the rendered image would (pose, fov, snapped camera)."""
        snap = None if self.snapped is None else id(self.snapped)
        return (tuple(np.round(self.position, 12)), tuple(np.round(self.rotation.reshape(-1), 12)),
                round(self.fov_y, 9), snap)

    def render_camera(self, width: int, height: int, name: str = "viewer") -> Camera:
        """The :class:`Camera` rendering ``width x height`` pixels from the current pose.

        While :attr:`snapped`, the evaluation camera's own intrinsics scaled to
        ``width x height`` (the caller keeps its aspect ratio, see
        :meth:`aspect`), so the image is exactly what the evaluation rendered.
        """
        if self.snapped is not None:
            return self.snapped.resized(int(width), int(height))
        return pinhole(self.rotation, self.position, self.fov_y, int(width), int(height), name)

    def aspect(self) -> float | None:
        """Width / height the image must have (the snapped camera's), or None (any)."""
        if self.snapped is None:
            return None
        return self.snapped.width / self.snapped.height

    # -- state changes --------------------------------------------------------
    def _moved(self) -> None:
        self.snapped = None
        self.rotation = orthonormalize(self.rotation)

    def set_mode(self, mode: str) -> None:
        if mode not in ("orbit", "fly"):
            raise ValueError(f"camera mode must be 'orbit' or 'fly', got {mode!r}")
        if mode == "orbit" and self.mode == "fly":
            # Keep the pivot in front of the camera at its former distance.
            dist = max(1e-6, float(np.linalg.norm(self.pivot - self.position)))
            self.pivot = self.position + self.forward * dist
        self.mode = mode

    def _clamp_pitch(self, axis_angle: float) -> float:
        """Limit a pitch rotation so forward stays PITCH_MARGIN_DEG away from +/- up."""
        f = self.forward
        theta = math.acos(max(-1.0, min(1.0, float(np.dot(f, self.up)))))  # angle forward-up
        margin = math.radians(PITCH_MARGIN_DEG)
        # A positive rotation about the right axis moves forward towards -down, i.e.
        # towards up when the camera is level: theta decreases by the angle.
        sign = 1.0 if np.dot(np.cross(self.right, f), self.up) >= 0 else -1.0
        new_theta = theta - sign * axis_angle
        new_theta = min(math.pi - margin, max(margin, new_theta))
        return sign * (theta - new_theta)

    def orbit(self, dx: float, dy: float) -> None:
        """Turn around the pivot by a mouse drag of (dx, dy) pixels."""
        yaw = rotation_about(self.up, -dx * self.rotate_speed)
        rel = yaw @ (self.position - self.pivot)
        rot = yaw @ self.rotation
        self.rotation = rot
        pitch = self._clamp_pitch(-dy * self.rotate_speed)
        p = rotation_about(self.right, pitch)
        self.position = self.pivot + p @ rel
        self.rotation = p @ rot
        self._moved()

    def look(self, dx: float, dy: float) -> None:
        """Mouse look (fly mode): turn in place by a drag of (dx, dy) pixels."""
        yaw = rotation_about(self.up, -dx * self.rotate_speed)
        self.rotation = yaw @ self.rotation
        pitch = self._clamp_pitch(-dy * self.rotate_speed)
        self.rotation = rotation_about(self.right, pitch) @ self.rotation
        self._moved()

    def drag(self, dx: float, dy: float) -> None:
        """A left-button drag: orbit or look, by mode."""
        if self.mode == "orbit":
            self.orbit(dx, dy)
        else:
            self.look(dx, dy)

    def pan(self, dx: float, dy: float, viewport_height: int) -> None:
        """Slide camera and pivot in the image plane so the pivot's depth plane follows the mouse."""
        dist = max(1e-6, float(np.dot(self.pivot - self.position, self.forward)))
        per_px = 2.0 * dist * math.tan(math.radians(self.fov_y) / 2.0) / max(1, viewport_height)
        shift = (-dx * self.right - dy * self.down) * per_px
        self.position = self.position + shift
        self.pivot = self.pivot + shift
        self._moved()

    def zoom(self, steps: float) -> None:
        """Mouse wheel: orbit -> scale the distance to the pivot by 0.9**steps; fly -> step forward."""
        if self.mode == "orbit":
            rel = self.position - self.pivot
            self.position = self.pivot + rel * (0.9 ** steps)
        else:
            self.position = self.position + self.forward * (0.1 * self.speed * steps)
        self._moved()

    def move(self, forward: float, right: float, up: float, dt: float, modifiers=()) -> None:
        """WASD / QE motion for ``dt`` seconds: each of ``forward``, ``right``, ``up`` is -1, 0 or 1.

        Forward and right follow the camera; up follows the world up.  In orbit
        mode the pivot moves along, so the orbit stays centred on what is ahead.
        """
        if not (forward or right or up) or dt <= 0:
            return
        factor = 1.0
        for m in modifiers:
            factor *= SPEED_MODIFIERS.get(m, 1.0)
        step = self.speed * factor * dt
        delta = (self.forward * forward + self.right * right + self.up * up) * step
        self.position = self.position + delta
        self.pivot = self.pivot + delta
        self._moved()

    def set_fov(self, fov_y: float) -> None:
        """Set the vertical field of view (degrees, clamped to [FOV_MIN, FOV_MAX])."""
        fov_y = float(min(FOV_MAX, max(FOV_MIN, fov_y)))
        if fov_y != self.fov_y:
            self.fov_y = fov_y
            self._moved()

    def reset(self) -> None:
        """Back to the pose the controller was created with."""
        if self.home is not None:
            pos, rot, fov, pivot = self.home
            self.position, self.rotation, self.fov_y, self.pivot = pos.copy(), rot.copy(), fov, pivot.copy()
            self.snapped = None

    def focus(self, centre: np.ndarray, radius: float) -> None:
        """Look at a sphere (``centre``, ``radius``) from the current direction so it fills the view."""
        centre = np.asarray(centre, dtype=np.float64)
        half = math.radians(self.fov_y) / 2.0
        dist = max(float(radius), 1e-6) / math.sin(half) * 1.1
        self.pivot = centre.copy()
        self.position = centre - self.forward * dist
        self._moved()

    def set_camera(self, camera: Camera) -> None:
        """Jump onto ``camera`` (pose and field of view); the image is then exactly that view.

        The orbit pivot moves onto the new optical axis, at the depth of the old pivot seen
        from the new camera (so orbiting still turns around the same object).
        """
        self.position = camera.center.copy()
        self.rotation = camera.R.T.copy()
        self.fov_y = fov_of(camera)
        dist = float(np.dot(self.pivot - self.position, self.forward))
        if not (dist > 1e-6):
            dist = self.speed * 2.0
        self.pivot = self.position + self.forward * dist
        self.snapped = camera

    def level(self) -> None:
        """Remove roll: keep the forward direction, make the image's vertical follow world up."""
        try:
            self.rotation = look_rotation(self.forward, self.up)
        except ValueError:
            return  # looking straight along up: no horizon to level
        self._moved()

    def set_up(self, choice: str, cameras: list[Camera] | None = None) -> None:
        """Use ``choice`` (an :data:`UP_CHOICES` entry) as world up and level the camera."""
        self.up = up_vector(choice, cameras)
        self.up_choice = choice
        self.level()

    def cycle_up(self, cameras: list[Camera] | None = None) -> None:
        """Next :data:`UP_CHOICES` entry as world up (the "camera up-axis fix")."""
        i = UP_CHOICES.index(self.up_choice) if self.up_choice in UP_CHOICES else -1
        self.set_up(UP_CHOICES[(i + 1) % len(UP_CHOICES)], cameras)
