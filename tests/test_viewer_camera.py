"""Orbit / fly camera controller (pure numpy)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.io import Camera
from r360gpu.viewer import camera as vc
from r360gpu.viewer.camera import CameraController, look_rotation

UP = np.array([0.0, 0.0, 1.0])


def level_controller(mode="orbit") -> CameraController:
    pos = np.array([0.0, -3.0, 0.0])
    return CameraController(position=pos.copy(), rotation=look_rotation(-pos, UP), pivot=np.zeros(3), up=UP,
                            mode=mode, speed=2.0)


def orbit_ring(n=8, radius=3.0, z=1.0, centre=(0.2, -0.1, 0.3)) -> list[Camera]:
    centre = np.asarray(centre)
    cams = []
    for i in range(n):
        a = 2 * math.pi * i / n
        eye = centre + np.array([radius * math.cos(a), radius * math.sin(a), z])
        c2w = np.eye(4)
        c2w[:3, :3] = look_rotation(centre - eye, UP)
        c2w[:3, 3] = eye
        cams.append(Camera.from_camera_to_world(c2w, 50, 50, 32, 24, 64, 48, f"v{i}"))
    return cams


def test_look_rotation_is_level_and_looks_forward():
    f = np.array([1.0, 2.0, -0.5])
    c = look_rotation(f, UP)
    assert np.allclose(c.T @ c, np.eye(3)) and np.linalg.det(c) > 0
    assert np.allclose(c[:, 2], f / np.linalg.norm(f))
    assert abs(np.dot(c[:, 0], UP)) < 1e-12  # right axis horizontal: no roll
    assert np.dot(c[:, 1], UP) < 0  # image down points to world down
    with pytest.raises(ValueError):
        look_rotation(UP, UP)


def test_orbit_keeps_distance_and_follows_the_mouse():
    c = level_controller()
    right0, down0, p0 = c.right, c.down, c.position.copy()
    c.orbit(10, 0)
    assert math.isclose(np.linalg.norm(c.position - c.pivot), 3.0, rel_tol=1e-12)
    assert np.dot(c.position - p0, right0) < 0  # drag right: the camera goes left around the pivot
    c = level_controller()
    c.orbit(0, 10)
    assert np.dot(c.position - p0, down0) < 0  # drag down: the camera rises
    # It keeps looking at the pivot.
    assert np.allclose(np.cross(c.forward, c.pivot - c.position), 0, atol=1e-9)


def test_orbit_pitch_never_flips_over_the_pole():
    c = level_controller()
    for _ in range(100):
        c.orbit(0, 50)
    angle = math.degrees(math.acos(np.clip(np.dot(c.forward, -UP), -1, 1)))
    assert vc.PITCH_MARGIN_DEG - 1e-6 <= angle < 5.0  # pushed to the pole, not over it
    assert abs(np.dot(c.right, UP)) < 1e-9  # still level


def test_look_turns_in_place():
    c = level_controller("fly")
    p0, right0, down0 = c.position.copy(), c.right, c.down
    c.look(10, 0)
    assert np.array_equal(c.position, p0)
    assert np.dot(c.forward, right0) > 0  # drag right: look right
    c = level_controller("fly")
    c.look(0, 10)
    assert np.dot(c.forward, down0) > 0  # drag down: look down


def test_move_speed_and_modifiers():
    c = level_controller("fly")
    p0, f0 = c.position.copy(), c.forward
    c.move(1, 0, 0, 0.5)
    assert np.allclose(c.position - p0, f0 * 2.0 * 0.5)
    p1 = c.position.copy()
    c.move(0, 0, 1, 0.5, modifiers=("Shift",))
    assert np.allclose(c.position - p1, UP * 2.0 * 0.5 * 4.0)
    p2 = c.position.copy()
    c.move(0, -1, 0, 1.0, modifiers=("Control",))
    assert np.allclose(c.position - p2, -c.right * 2.0 * 0.25)


def test_orbit_move_carries_the_pivot_and_pan_keeps_the_offset():
    c = level_controller()
    offset = c.position - c.pivot
    c.move(1, 1, 0, 0.25)
    assert np.allclose(c.position - c.pivot, offset)
    c.pan(30, -20, 480)
    assert np.allclose(c.position - c.pivot, offset)


def test_zoom_scales_orbit_distance():
    c = level_controller()
    c.zoom(2)
    assert math.isclose(np.linalg.norm(c.position - c.pivot), 3.0 * 0.81, rel_tol=1e-12)


def test_set_camera_renders_exactly_that_camera():
    cam = orbit_ring()[3]
    c = level_controller()
    c.set_camera(cam)
    assert c.snapped is cam and c.aspect() == pytest.approx(64 / 48)
    r = c.render_camera(64, 48)
    assert np.allclose(r.R, cam.R) and np.allclose(r.t, cam.t)
    assert (r.fx, r.fy, r.cx, r.cy, r.width, r.height) == (cam.fx, cam.fy, cam.cx, cam.cy, 64, 48)
    half = c.render_camera(32, 24)
    assert (half.fx, half.cx) == (cam.fx / 2, cam.cx / 2)
    c.orbit(1, 0)
    assert c.snapped is None
    ring = CameraController.for_cameras(orbit_ring(centre=(0.2, -0.1, 0.3)))
    ring.set_camera(orbit_ring(centre=(0.2, -0.1, 0.3))[5])
    assert np.allclose(ring.pivot, (0.2, -0.1, 0.3))  # still orbiting the object the cameras look at


def test_free_camera_projects_the_pivot_to_the_centre():
    c = level_controller()
    cam = c.render_camera(80, 60)
    uv, z = cam.project(c.pivot[None])
    assert np.allclose(uv[0], (40, 30)) and math.isclose(z[0], 3.0)
    assert math.isclose(vc.fov_of(cam), c.fov_y)


def test_focus_fits_the_sphere():
    c = level_controller()
    centre, radius = np.array([1.0, 2.0, 0.5]), 0.4
    c.focus(centre, radius)
    cam = c.render_camera(100, 100)
    d = np.linalg.norm(c.position - centre)
    assert math.asin(radius / d) < math.radians(c.fov_y) / 2
    uv, _ = cam.project(centre[None])
    assert np.allclose(uv[0], (50, 50))


def test_level_removes_roll_and_up_cycles():
    c = level_controller()
    c.rotation = vc.rotation_about(c.forward, 0.3) @ c.rotation
    assert abs(np.dot(c.right, UP)) > 0.1
    f = c.forward
    c.level()
    assert abs(np.dot(c.right, UP)) < 1e-12 and np.allclose(c.forward, f)
    cams = orbit_ring()
    seen = []
    for _ in vc.UP_CHOICES:
        c.cycle_up(cams)
        seen.append(c.up_choice)
    assert seen == list(vc.UP_CHOICES[1:]) + [vc.UP_CHOICES[0]]
    assert np.allclose(c.up, UP)  # "auto" estimated from the upright ring


def test_mode_switch_puts_the_pivot_ahead():
    c = level_controller("fly")
    c.look(40, 0)
    c.set_mode("orbit")
    assert np.allclose(np.cross(c.forward, c.pivot - c.position), 0, atol=1e-9)
    with pytest.raises(ValueError):
        c.set_mode("walk")


def test_reset_and_fov_limits():
    cams = orbit_ring()
    c = CameraController.for_cameras(cams, start=2)
    home = c.position.copy()
    c.orbit(30, 10)
    c.set_fov(500)
    assert c.fov_y == vc.FOV_MAX
    c.reset()
    assert np.allclose(c.position, home) and c.snapped is None


def test_scene_estimates():
    cams = orbit_ring(centre=(0.2, -0.1, 0.3))
    assert np.allclose(vc.estimate_up(cams), UP)
    assert np.allclose(vc.look_at_point(cams), (0.2, -0.1, 0.3), atol=1e-9)
    assert math.isclose(vc.scene_scale(cams), math.hypot(3.0, 0.0), rel_tol=1e-9)
    assert np.allclose(vc.estimate_up([]), (0, -1, 0))


def test_nearest_camera_and_interpolation():
    cams = orbit_ring()
    c = level_controller()
    c.set_camera(cams[5])
    c.orbit(5, 0)
    assert vc.nearest_camera(c.position, c.rotation, cams, 3.0) == 5
    a, b = cams[0], cams[1]
    start, end = vc.interpolate(a, b, 0.0), vc.interpolate(a, b, 1.0)
    assert np.allclose(start.R, a.R) and np.allclose(start.center, a.center)
    assert np.allclose(end.R, b.R) and np.allclose(end.center, b.center)
    mid = vc.interpolate(a, b, 0.5)
    ang = lambda r1, r2: math.acos(np.clip((np.trace(r1.T @ r2) - 1) / 2, -1, 1))  # noqa: E731
    assert math.isclose(ang(a.R, mid.R), ang(a.R, b.R) / 2, rel_tol=1e-6)
