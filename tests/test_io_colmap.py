"""COLMAP sparse model reader and writer."""
from __future__ import annotations

import math
import struct
import warnings

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.camera import Camera
from r360gpu.io.colmap import load_colmap, read_images_text, save_colmap
from r360gpu.io.rotation import quat_to_rotmat

S = math.sqrt(0.5)
CAMERAS_TXT = """# Camera list
1 PINHOLE 640 480 500 510 320 240
2 SIMPLE_RADIAL 800 600 700 400 300 0.1
"""
IMAGES_TXT = f"""# Image list
1 1 0 0 0 0 0 5 1 a.png
1.0 2.0 -1 3 4 5
2 {S} 0 {S} 0 0 0 4 2 sub/b.png

"""


def _text_model(folder, cameras=CAMERAS_TXT, images=IMAGES_TXT):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cameras.txt").write_text(cameras)
    (folder / "images.txt").write_text(images)
    return folder


def _binary_model(folder, cameras=None, images=None):
    """The model of CAMERAS_TXT/IMAGES_TXT packed by hand with struct."""
    folder.mkdir(parents=True, exist_ok=True)
    cameras = cameras if cameras is not None else (
        struct.pack("<Q", 2)
        + struct.pack("<iiQQ", 1, 1, 640, 480) + struct.pack("<4d", 500, 510, 320, 240)
        + struct.pack("<iiQQ", 2, 2, 800, 600) + struct.pack("<4d", 700, 400, 300, 0.1))
    images = images if images is not None else (
        struct.pack("<Q", 2)
        + struct.pack("<i7di", 1, 1, 0, 0, 0, 0, 0, 5, 1) + b"a.png\0"
        + struct.pack("<Q", 2) + struct.pack("<ddq", 1.0, 2.0, -1) + struct.pack("<ddq", 3, 4, 5)
        + struct.pack("<i7di", 2, S, 0, S, 0, 0, 0, 4, 2) + b"sub/b.png\0" + struct.pack("<Q", 0))
    (folder / "cameras.bin").write_bytes(cameras)
    (folder / "images.bin").write_bytes(images)
    return folder


def _check_known_pixels(cams):
    a, b = cams
    assert (a.name, b.name) == ("a.png", "sub/b.png")
    assert (a.width, a.height, b.width, b.height) == (640, 480, 800, 600)
    # Image 1: identity rotation, t = (0, 0, 5): (1, 2, 5) -> camera (1, 2, 10).
    uv, z = a.project([[1.0, 2.0, 5.0]])
    np.testing.assert_allclose(uv, [[500 * 0.1 + 320, 510 * 0.2 + 240]])
    assert z[0] == 10.0
    # Image 2: qvec = 90 degrees about y, t = (0, 0, 4): (2, 1, -1) -> camera (-1, 1, 2).
    uv, z = b.project([[2.0, 1.0, -1.0]])
    np.testing.assert_allclose(uv, [[700 * -0.5 + 400, 700 * 0.5 + 300]], atol=1e-12)
    np.testing.assert_allclose(z, [2.0], atol=1e-15)
    np.testing.assert_allclose(b.center, [4.0, 0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("kind", ["text", "binary"])
def test_known_point_projects_to_known_pixel(tmp_path, kind):
    folder = (_text_model if kind == "text" else _binary_model)(tmp_path / "sparse" / "0")
    with pytest.warns(R360Warning, match="SIMPLE_RADIAL have lens distortion"):
        cams = load_colmap(folder)
    _check_known_pixels(cams)
    ext = ".txt" if kind == "text" else ".bin"
    with pytest.warns(R360Warning):
        _check_known_pixels(load_colmap(folder / f"images{ext}"))


def test_binary_preferred_over_text(tmp_path):
    folder = _binary_model(tmp_path / "m")
    _text_model(folder, images=IMAGES_TXT.replace("a.png", "text.png"))
    with pytest.warns(R360Warning):
        assert load_colmap(folder)[0].name == "a.png"
        assert load_colmap(folder / "cameras.txt")[0].name == "text.png"


def test_one_warning_naming_all_distorted_models(tmp_path):
    cams = ("1 OPENCV 10 10 5 5 5 5 0 0 0 0\n"          # zero distortion: exact, not reported
            "2 RADIAL 10 10 7 4 3 0.1 0\n"
            "3 OPENCV_FISHEYE 10 10 5 5 5 5 0 0 0 0\n")   # fisheye: always reported
    imgs = "".join(f"{i} 1 0 0 0 0 0 1 {i} im{i}.png\n\n" for i in (1, 2, 3, 2))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        out = load_colmap(_text_model(tmp_path / "m", cams, imgs))
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert len(out) == 4 and len(msgs) == 1
    assert "OPENCV_FISHEYE, RADIAL have" in msgs[0]
    assert (out[1].fx, out[1].fy, out[1].cx, out[1].cy) == (7, 7, 4, 3)


def test_exact_models_do_not_warn(tmp_path):
    cams = "1 SIMPLE_PINHOLE 100 50 80 50 25\n2 OPENCV 10 10 5 6 5 5 0 0 0 0\n"
    imgs = "1 1 0 0 0 0 0 1 1 x.png\n\n2 1 0 0 0 0 0 1 2 y.png\n\n"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a, b = load_colmap(_text_model(tmp_path / "m", cams, imgs))
    assert (a.fx, a.fy, a.cx, a.cy) == (80, 80, 50, 25)
    assert (b.fx, b.fy) == (5, 6)


@pytest.mark.parametrize("binary", [True, False])
def test_writer_round_trip(tmp_path, binary):
    rng = np.random.default_rng(1)
    cams = [Camera(quat_to_rotmat(rng.normal(size=4)), rng.normal(size=3) * 3, 400 + i, 420.5, 319.5 + i,
                   241.25, 640, 480, f"frame_{i:03d}.jpg") for i in range(6)]
    save_colmap(tmp_path / "m", cams, binary=binary)
    ext = "bin" if binary else "txt"
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == sorted(
        [f"cameras.{ext}", f"images.{ext}", f"points3D.{ext}"])
    got = load_colmap(tmp_path / "m")
    for a, b in zip(cams, got):
        assert a.name == b.name and (a.width, a.height) == (b.width, b.height)
        assert (a.fx, a.fy, a.cx, a.cy) == (b.fx, b.fy, b.cx, b.cy)
        np.testing.assert_allclose(b.R, a.R, atol=1e-14)
        np.testing.assert_allclose(b.t, a.t, atol=1e-14)


def test_writer_rejects_unstorable_names(tmp_path):
    cam = Camera(np.eye(3), [0, 0, 0], 1, 1, 0, 0, 2, 2, "bad\nname")
    with pytest.raises(ValueError, match="cannot be stored"):
        save_colmap(tmp_path / "m", [cam])


@pytest.mark.parametrize("cameras,images,msg", [
    ("1 PINHOLE 640 480 500 510 320\n", IMAGES_TXT, "PINHOLE needs 4 parameters, got 3"),
    ("1 FANCY 640 480 1 2 3\n", IMAGES_TXT, "unsupported camera model 'FANCY'"),
    ("1 PINHOLE 640 abc 1 2 3 4\n", IMAGES_TXT, "line 1: malformed camera line"),
    (CAMERAS_TXT, IMAGES_TXT.replace(" 2 sub/b.png", " 9 sub/b.png"), "refers to camera 9"),
    (CAMERAS_TXT, "1 1 0 0 0 0 0 5 1 a.png\n2 1 0 0 0 0 0 5 1 b.png\n", "line 2: expected the POINTS2D"),
    (CAMERAS_TXT, "1 1 0 0 0 0 0 1 a.png\n\n", "malformed image line"),
    (CAMERAS_TXT, "1 0 0 0 0 0 0 5 1 a.png\n\n", "invalid qvec"),
    ("1 PINHOLE 640 480 -5 510 320 240\n", "1 1 0 0 0 0 0 5 1 a.png\n\n", "camera 'a.png': focal lengths"),
    ("1 PINHOLE 0 480 5 510 320 240\n", "1 1 0 0 0 0 0 5 1 a.png\n\n", "width must be a positive"),
])
def test_bad_text_models(tmp_path, cameras, images, msg):
    with pytest.raises(InputError, match=msg):
        load_colmap(_text_model(tmp_path / "m", cameras, images))


def test_bad_binary_models(tmp_path):
    good = _binary_model(tmp_path / "good")
    cams, imgs = (good / "cameras.bin").read_bytes(), (good / "images.bin").read_bytes()
    cases = [
        (cams[:-4], imgs, "cameras.bin: truncated while reading camera 2 parameters"),
        (cams, imgs[:-30], "images.bin: truncated"),
        (cams + b"\0", imgs, "1 bytes after the records"),
        (struct.pack("<Q", 3) + cams[8:], imgs, "truncated while reading camera record"),
        (struct.pack("<Q", 1) + struct.pack("<iiQQ", 1, 99, 1, 1), imgs, "unsupported camera model id 99"),
        (cams, imgs.replace(b"sub/b.png\0", b"sub/b.png"), "images.bin: truncated"),
    ]
    for i, (c, m, msg) in enumerate(cases):
        with pytest.raises(InputError, match=msg):
            load_colmap(_binary_model(tmp_path / f"bad{i}", c, m))


def test_missing_files(tmp_path):
    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "cameras.txt").write_text(CAMERAS_TXT)
    with pytest.raises(InputError, match="missing images.txt"):
        load_colmap(folder)
    with pytest.raises(InputError, match="no such file"):
        load_colmap(tmp_path / "nothing")


def test_images_text_name_with_spaces_and_trailing_line(tmp_path):
    p = tmp_path / "images.txt"
    p.write_text("# c\n3 1 0 0 0 1 2 3 1 my image.png")
    (im,) = read_images_text(p)
    assert im.name == "my image.png" and im.tvec == (1.0, 2.0, 3.0)
