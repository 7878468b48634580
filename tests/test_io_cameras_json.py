"""INRIA cameras.json reader and writer."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.camera import Camera
from r360gpu.io.cameras_json import load_cameras_json, save_cameras_json
from r360gpu.io.rotation import quat_to_rotmat

RY90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def _inria_entry(r_w2c, t, idx=0, name="img", width=100, height=80, fx=100.0, fy=200.0):
    """What INRIA's camera_to_JSON stores for a COLMAP pose (R_w2c, t): the blocks of the
    inverse of [[R_w2c, t], [0, 1]]."""
    rt = np.eye(4)
    rt[:3, :3], rt[:3, 3] = r_w2c, t
    inv = np.linalg.inv(rt)
    return {"id": idx, "img_name": name, "width": width, "height": height,
            "position": inv[:3, 3].tolist(), "rotation": [row.tolist() for row in inv[:3, :3]],
            "fy": fy, "fx": fx}


def test_known_point_projects_to_known_pixel(tmp_path):
    p = tmp_path / "cameras.json"
    p.write_text(json.dumps([_inria_entry(RY90, [0.0, 0.0, 4.0])]))
    (cam,) = load_cameras_json(p)
    assert cam.name == "img" and (cam.cx, cam.cy) == (50.0, 40.0)  # no principal point: centre
    np.testing.assert_allclose(cam.center, [4, 0, 0], atol=1e-15)
    # R @ (2, 1, -1) + t = (-1, 1, 2): u = 100 * -1/2 + 50, v = 200 * 1/2 + 40.
    uv, z = cam.project([[2.0, 1.0, -1.0]])
    np.testing.assert_allclose(uv, [[0.0, 140.0]], atol=1e-12)
    np.testing.assert_allclose(z, [2.0])


def test_stored_rotation_is_camera_to_world(tmp_path):
    entry = _inria_entry(RY90, [0.0, 0.0, 4.0])
    np.testing.assert_allclose(entry["rotation"], RY90.T, atol=1e-15)
    np.testing.assert_allclose(entry["position"], [4, 0, 0], atol=1e-15)


def test_optional_principal_point(tmp_path):
    entry = _inria_entry(np.eye(3), [0, 0, 0])
    entry.update(cx=10.5, cy=20.25)
    p = tmp_path / "c.json"
    p.write_text(json.dumps([entry]))
    (cam,) = load_cameras_json(p)
    assert (cam.cx, cam.cy) == (10.5, 20.25)


def test_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    cams = [Camera(quat_to_rotmat(rng.normal(size=4)), rng.normal(size=3), 300.0 + i, 310.0, 100.5, 80.0,
                   200, 160, f"v{i}") for i in range(4)]
    save_cameras_json(tmp_path / "cameras.json", cams)
    doc = json.loads((tmp_path / "cameras.json").read_text())
    assert [e["id"] for e in doc] == [0, 1, 2, 3]
    assert set(doc[0]) == {"id", "img_name", "width", "height", "position", "rotation", "fx", "fy", "cx", "cy"}
    got = load_cameras_json(tmp_path / "cameras.json")
    for a, b in zip(cams, got):
        assert (a.name, a.fx, a.fy, a.cx, a.cy, a.width, a.height) == (b.name, b.fx, b.fy, b.cx, b.cy,
                                                                        b.width, b.height)
        np.testing.assert_allclose(b.R, a.R, atol=1e-14)
        np.testing.assert_allclose(b.t, a.t, atol=1e-14)


@pytest.mark.parametrize("doc,msg", [
    ({"frames": []}, "must hold a list"),
    ([], "holds no cameras"),
    ([5], "entry 0 is not an object"),
    ([{"img_name": "a", "width": 1}], "entry 0: missing keys height, position, rotation, fx, fy"),
])
def test_bad_documents(tmp_path, doc, msg):
    p = tmp_path / "cameras.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=msg):
        load_cameras_json(p)


@pytest.mark.parametrize("change,msg", [
    (dict(rotation=(2 * np.eye(3)).tolist()), "camera 'img': not a rotation"),
    (dict(rotation=[[1, 0], [0, 1]]), "finite 3x3"),
    (dict(position=[0, 0]), "position must have 3"),
    (dict(position=[0, float("nan"), 0]), "finite"),
    (dict(fx="100"), "fx must be a number"),
    (dict(width=0), "width must be a positive"),
    (dict(rotation="I"), "not numeric"),
])
def test_bad_values(tmp_path, change, msg):
    entry = _inria_entry(np.eye(3), [0, 0, 1])
    entry.update(change)
    p = tmp_path / "cameras.json"
    p.write_text(json.dumps([entry]))
    with pytest.raises(InputError, match=msg):
        load_cameras_json(p)


def test_unreadable_json(tmp_path):
    p = tmp_path / "cameras.json"
    p.write_text("[{")
    with pytest.raises(InputError, match="invalid JSON"):
        load_cameras_json(p)
    p.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match="UTF-8"):
        load_cameras_json(p)
    with pytest.raises(InputError, match="cannot read"):
        load_cameras_json(tmp_path / "none.json")
