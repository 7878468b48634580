"""nerfstudio / instant-ngp transforms.json reader and writer."""
from __future__ import annotations

import json
import math
import warnings

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.camera import Camera
from r360gpu.io.rotation import quat_to_rotmat
from r360gpu.io.transforms_json import load_transforms_json, save_transforms_json

# Camera at (0, 0, 5), axes aligned with the world: in OpenGL axes it looks along -z world.
AT_Z5 = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]]


def _write(path, doc):
    path.write_text(json.dumps(doc))
    return path


def test_blender_style_file_with_image_size_from_png(tmp_path):
    (tmp_path / "train").mkdir()
    cv2.imwrite(str(tmp_path / "train" / "r_0.png"), np.zeros((30, 40, 4), np.uint8))
    doc = {"camera_angle_x": math.pi / 2, "frames": [{"file_path": "./train/r_0", "transform_matrix": AT_Z5}]}
    (cam,) = load_transforms_json(_write(tmp_path / "transforms_train.json", doc))
    assert cam.name == "train/r_0" and (cam.width, cam.height) == (40, 30)
    # fl_x = 0.5 * 40 / tan(45 deg) = 20 = fl_y; principal point at the centre (20, 15).
    assert cam.fx == pytest.approx(20) and cam.fy == pytest.approx(20) and (cam.cx, cam.cy) == (20, 15)
    np.testing.assert_allclose(cam.center, [0, 0, 5])
    # (1, 1, 0) is 5 in front, right and UP (world y up) -> right of and above the centre.
    uv, z = cam.project([[1.0, 1.0, 0.0]])
    np.testing.assert_allclose(uv, [[20 + 20 * 0.2, 15 - 20 * 0.2]], atol=1e-12)
    np.testing.assert_allclose(z, [5.0])


def test_rotated_camera_by_hand(tmp_path):
    # Camera-to-world (GL): camera x -> world -z, camera y -> world y, camera z (backwards) -> world x.
    # So the camera at the origin looks along -x world.
    c2w = [[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0]]  # 3x4 accepted
    doc = {"fl_x": 100, "fl_y": 110, "cx": 60, "cy": 50, "w": 120, "h": 100,
           "frames": [{"file_path": "a.jpg", "transform_matrix": c2w}]}
    (cam,) = load_transforms_json(_write(tmp_path / "transforms.json", doc))
    # World (-4, 2, -1): depth 4 along -x, 1 along camera x (world -z), 2 up -> camera-CV (1, -2, 4).
    uv, z = cam.project([[-4.0, 2.0, -1.0]])
    np.testing.assert_allclose(uv, [[100 * 0.25 + 60, 110 * -0.5 + 50]], atol=1e-12)
    np.testing.assert_allclose(z, [4.0], atol=1e-15)


def test_per_frame_intrinsics_override_global_and_defaults(tmp_path):
    doc = {"fl_x": 100, "w": 200, "h": 100, "camera_angle_y": 2 * math.atan(0.25),
           "frames": [{"file_path": "a", "transform_matrix": AT_Z5},
                      {"file_path": "b", "transform_matrix": AT_Z5, "fl_x": 50, "cx": 3, "h": 40}]}
    a, b = load_transforms_json(_write(tmp_path / "t.json", doc))
    assert (a.fx, a.cx, a.cy, a.height) == (100, 100, 50, 100)
    assert a.fy == pytest.approx(0.5 * 100 / 0.25)  # from camera_angle_y
    assert (b.fx, b.cx, b.cy, b.height) == (50, 3, 20, 40)
    assert b.fy == pytest.approx(0.5 * 40 / 0.25)


def test_fy_defaults_to_fx(tmp_path):
    doc = {"fl_x": 70, "w": 20, "h": 10, "frames": [{"file_path": "a", "transform_matrix": AT_Z5}]}
    (cam,) = load_transforms_json(_write(tmp_path / "t.json", doc))
    assert cam.fy == 70


def test_image_size_of_non_png_via_opencv(tmp_path):
    cv2.imwrite(str(tmp_path / "f.jpg"), np.zeros((12, 34, 3), np.uint8))
    doc = {"fl_x": 10, "frames": [{"file_path": "f.jpg", "transform_matrix": AT_Z5}]}
    (cam,) = load_transforms_json(_write(tmp_path / "t.json", doc))
    assert (cam.width, cam.height) == (34, 12)


def test_distortion_and_fisheye_warn_once(tmp_path):
    frames = [{"file_path": f"{i}", "transform_matrix": AT_Z5} for i in range(3)]
    doc = {"fl_x": 10, "w": 20, "h": 10, "k1": 0.01, "p2": 0, "frames": frames}
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert len(load_transforms_json(_write(tmp_path / "t.json", doc))) == 3
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert len(msgs) == 1 and "OPENCV with non-zero distortion" in msgs[0]
    doc.update(camera_model="OPENCV_FISHEYE", k1=0)
    with pytest.warns(R360Warning, match="OPENCV_FISHEYE cameras"):
        load_transforms_json(_write(tmp_path / "t.json", doc))
    doc.update(camera_model="PINHOLE")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_transforms_json(_write(tmp_path / "t.json", doc))


def test_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    cams = [Camera(quat_to_rotmat(rng.normal(size=4)), rng.normal(size=3), 500.0, 501.0 + i, 320.0, 240.5,
                   640, 480, f"images/f{i}.png") for i in range(5)]
    save_transforms_json(tmp_path / "transforms.json", cams)
    doc = json.loads((tmp_path / "transforms.json").read_text())
    assert doc["camera_model"] == "PINHOLE" and len(doc["frames"]) == 5
    # Stored matrix is camera-to-world with OpenGL axes: its z column points backwards.
    m = np.array(doc["frames"][0]["transform_matrix"])
    np.testing.assert_allclose(m[:3, 2], -cams[0].R[2], atol=1e-15)
    np.testing.assert_allclose(m[:3, 3], cams[0].center, atol=1e-15)
    got = load_transforms_json(tmp_path / "transforms.json")
    for a, b in zip(cams, got):
        assert (a.name, a.fx, a.fy, a.cx, a.cy, a.width, a.height) == (b.name, b.fx, b.fy, b.cx, b.cy,
                                                                        b.width, b.height)
        np.testing.assert_allclose(b.R, a.R, atol=1e-14)
        np.testing.assert_allclose(b.t, a.t, atol=1e-14)


@pytest.mark.parametrize("doc,msg", [
    ([], "object with a 'frames' list"),
    ({"frames": []}, "no frames"),
    ({"frames": [3]}, "frame 0 is not an object"),
    ({"frames": [{"file_path": "a"}]}, "frame 0 \\('a'\\): no transform_matrix"),
    ({"fl_x": 1, "w": 2, "h": 2, "frames": [{"transform_matrix": [[1, 0], [0, 1]]}]}, "must be 4x4 or 3x4"),
    ({"fl_x": 1, "w": 2, "h": 2, "frames": [{"transform_matrix": "I"}]}, "not a numeric matrix"),
    ({"fl_x": 1, "w": 2, "h": 2, "frames": [{"transform_matrix": (2 * np.eye(4)).tolist()}]}, "not a rotation"),
    ({"w": 2, "h": 2, "frames": [{"transform_matrix": AT_Z5}]}, "no focal length"),
    ({"camera_angle_x": 4, "w": 2, "h": 2, "frames": [{"transform_matrix": AT_Z5}]}, "not in \\(0, pi\\)"),
    ({"fl_x": 1, "frames": [{"file_path": "missing", "transform_matrix": AT_Z5}]}, "image 'missing' not found"),
    ({"fl_x": 1, "w": "2", "h": 2, "frames": [{"transform_matrix": AT_Z5}]}, "w must be a number"),
    ({"fl_x": 1, "w": 2, "h": 2, "camera_model": "EQUIRECTANGULAR", "frames": [{"transform_matrix": AT_Z5}]},
     "not a perspective camera"),
    ({"fl_x": -1, "w": 2, "h": 2, "frames": [{"transform_matrix": AT_Z5}]}, "focal lengths must be > 0"),
])
def test_bad_documents(tmp_path, doc, msg):
    with pytest.raises(InputError, match=msg):
        load_transforms_json(_write(tmp_path / "transforms.json", doc))


def test_unreadable_image_for_size(tmp_path):
    (tmp_path / "x.jpg").write_bytes(b"not an image")
    doc = {"fl_x": 1, "frames": [{"file_path": "x.jpg", "transform_matrix": AT_Z5}]}
    with pytest.raises(InputError, match="cannot read image"):
        load_transforms_json(_write(tmp_path / "t.json", doc))
