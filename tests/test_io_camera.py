"""Camera conventions, projection and the rotation helpers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.camera import Camera, checked_rotation, make_camera
from r360gpu.io.rotation import nearest_rotation, quat_to_rotmat, rotmat_to_quat

# World-to-camera rotation: 90 degrees about y.
RY90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def _cam(**kw):
    args = dict(R=RY90, t=[0.0, 0.0, 4.0], fx=100.0, fy=200.0, cx=50.0, cy=40.0, width=100, height=80,
                name="v0")
    args.update(kw)
    return Camera(**args)


def test_project_known_point_by_hand():
    cam = _cam()
    # R @ (2, 1, -1) = (-1, 1, -2); + t = (-1, 1, 2): u = 100 * -1/2 + 50, v = 200 * 1/2 + 40.
    uv, z = cam.project(np.array([[2.0, 1.0, -1.0]]))
    np.testing.assert_allclose(uv, [[0.0, 140.0]])
    np.testing.assert_allclose(z, [2.0])


def test_center_and_matrices():
    cam = _cam()
    np.testing.assert_allclose(cam.center, [4.0, 0.0, 0.0])
    np.testing.assert_allclose(cam.world_to_camera @ cam.camera_to_world, np.eye(4), atol=1e-15)
    np.testing.assert_allclose(cam.world_to_camera[:3, 3], cam.t)
    np.testing.assert_allclose(cam.K, [[100, 0, 50], [0, 200, 40], [0, 0, 1]])
    # The optical axis (+z of the camera) hits the principal point.
    forward = cam.camera_to_world[:3, 2]
    uv, z = cam.project(cam.center + 3.0 * forward)
    np.testing.assert_allclose(uv[0], [cam.cx, cam.cy])
    assert z[0] == pytest.approx(3.0)


def test_points_behind_camera_give_nan_pixels():
    cam = _cam()
    forward = cam.camera_to_world[:3, 2]
    uv, z = cam.project(np.stack([cam.center - forward, cam.center, cam.center + forward]))
    assert np.isnan(uv[:2]).all() and np.isfinite(uv[2]).all()
    np.testing.assert_allclose(z, [-1.0, 0.0, 1.0], atol=1e-12)


def test_resized_scales_intrinsics_in_corner_convention():
    cam = _cam(cx=50.0, cy=40.0)
    small = cam.resized(50, 40)
    assert (small.fx, small.fy, small.cx, small.cy, small.width, small.height) == (50, 100, 25, 20, 50, 40)
    pts = np.array([[2.0, 1.0, -1.0], [4.5, -0.3, 0.2]])
    np.testing.assert_allclose(small.project(pts)[0], cam.project(pts)[0] / 2)


def test_from_camera_to_world():
    cam = _cam()
    again = Camera.from_camera_to_world(cam.camera_to_world, cam.fx, cam.fy, cam.cx, cam.cy,
                                        cam.width, cam.height, cam.name)
    np.testing.assert_allclose(again.R, cam.R, atol=1e-15)
    np.testing.assert_allclose(again.t, cam.t, atol=1e-15)


@pytest.mark.parametrize("kw,msg", [
    (dict(R=np.diag([1.0, 1.0, 2.0])), "rotation"),
    (dict(R=np.diag([1.0, 1.0, -1.0])), "rotation"),
    (dict(t=[0.0, np.nan, 0.0]), "finite"),
    (dict(fx=0.0), "focal"),
    (dict(cy=np.inf), "finite"),
    (dict(width=0), "positive integer"),
    (dict(height=10.5), "positive integer"),
])
def test_validation(kw, msg):
    with pytest.raises(ValueError, match=msg):
        _cam(**kw)


def test_arrays_are_private_readonly_copies():
    r = RY90.copy()
    cam = _cam(R=r)
    r[0, 0] = 5.0
    assert cam.R[0, 0] == 0.0 and not cam.R.flags.writeable and not cam.t.flags.writeable


def test_make_camera_turns_bad_values_into_input_error():
    with pytest.raises(InputError, match="cams.json: camera 'v7': focal lengths"):
        make_camera("cams.json", RY90, [0, 0, 0], -1.0, 1.0, 0, 0, 10, 10, "v7")


def test_quat_to_rotmat_by_hand():
    s = math.sqrt(0.5)
    r = quat_to_rotmat([s, 0.0, 0.0, s])  # 90 degrees about z
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(quat_to_rotmat([2.0, 0, 0, 0]), np.eye(3))
    stacked = quat_to_rotmat(np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]]))
    np.testing.assert_allclose(stacked[1], np.diag([1.0, -1.0, -1.0]))


def test_rotmat_to_quat_round_trip_including_half_turns():
    rng = np.random.default_rng(0)
    quats = list(rng.normal(size=(50, 4))) + [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 1, 1, 0]]
    for q in quats:
        q = np.asarray(q, float) / np.linalg.norm(q)
        got = rotmat_to_quat(quat_to_rotmat(q))
        assert got[0] >= 0
        np.testing.assert_allclose(got, q if q[0] >= 0 else -q, atol=1e-12)


def test_checked_rotation():
    noisy = RY90 + 1e-6 * np.arange(9).reshape(3, 3)
    fixed = checked_rotation(noisy, "f.json", "frame 0")
    np.testing.assert_allclose(fixed.T @ fixed, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(fixed, RY90, atol=1e-5)
    with pytest.raises(InputError, match="f.json: frame 0: not a rotation"):
        checked_rotation(2 * RY90, "f.json", "frame 0")
    with pytest.raises(InputError, match="not a rotation"):
        checked_rotation(-RY90, "f.json", "frame 0")
    with pytest.raises(InputError, match="finite 3x3"):
        checked_rotation(np.eye(2), "f.json", "frame 0")


def test_nearest_rotation_is_proper():
    r = nearest_rotation(np.diag([1.0, 1.0, -1.0]) + 1e-3)
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_key_tells_apart_what_decides_a_rendering_and_not_the_name():
    base = dict(R=np.eye(3), t=[0.0, 0.0, 1.0], fx=100.0, fy=100.0, cx=50.0, cy=40.0, width=100, height=80)
    key = Camera(**base, name="a").key()
    assert Camera(**{**base, "fx": 100, "width": 100.0}, name="b").key() == key  # the same numbers, typed otherwise
    hash(key)
    turned = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for field, value in [("R", turned), ("t", [0.0, 0.0, 1.0 + 1e-12]), ("fx", 100.5), ("fy", 99.0), ("cx", 50.5),
                         ("cy", 40.5), ("width", 101), ("height", 81)]:
        assert Camera(**{**base, field: value}).key() != key, field
