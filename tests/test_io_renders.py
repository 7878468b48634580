"""Renders input: RGB and depth images per view (PNG 8/16-bit, JPEG, EXR, NPY, TIFF), headers, reader."""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.exr import UnsupportedExrError, read_exr, read_exr_info
from r360gpu.io.renders import RendersReader, image_size, read_depth, read_rgb

EXR_DIR = Path(__file__).parent / "data" / "exr"
H, W = 9, 13


def rng_image(shape, dtype, seed=0):
    info = np.iinfo(dtype)
    return np.random.default_rng(seed).integers(0, int(info.max) + 1, shape, dtype=dtype)


# --- RGB -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("dtype, scale", [(np.uint8, 255.0), (np.uint16, 65535.0)])
def test_rgb_png_round_trip(tmp_path, dtype, scale):
    rgb = rng_image((H, W, 3), dtype)
    path = tmp_path / "v.png"
    cv2.imwrite(str(path), rgb[:, :, ::-1])  # OpenCV writes BGR
    out = read_rgb(path)
    assert out.dtype == np.float32 and out.shape == (H, W, 3)
    np.testing.assert_array_equal(out, (rgb / np.float32(scale)).astype(np.float32))


def test_rgb_grey_rgba_and_jpeg(tmp_path):
    grey = rng_image((H, W), np.uint8)
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    np.testing.assert_array_equal(read_rgb(tmp_path / "g.png"), np.repeat(grey[:, :, None] / np.float32(255), 3, 2))
    rgba = rng_image((H, W, 4), np.uint8)
    cv2.imwrite(str(tmp_path / "a.png"), rgba)
    np.testing.assert_array_equal(read_rgb(tmp_path / "a.png"), rgba[:, :, 2::-1] / np.float32(255))
    flat = np.zeros((H, W, 3), np.uint8)
    flat[...] = (200, 100, 50)  # BGR on disk
    cv2.imwrite(str(tmp_path / "j.jpg"), flat)
    out = read_rgb(tmp_path / "j.jpg")
    np.testing.assert_allclose(out[0, 0], np.array([50, 100, 200]) / 255, atol=3 / 255)
    assert 0.0 <= out.min() and out.max() <= 1.0


def test_rgb_errors_name_the_file(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match=r"bad\.png: cannot decode image"):
        read_rgb(tmp_path / "bad.png")
    with pytest.raises(InputError, match=r"missing\.png: cannot read file"):
        read_rgb(tmp_path / "missing.png")
    cv2.imwrite(str(tmp_path / "f.tiff"), np.zeros((H, W, 3), np.float32))
    with pytest.raises(InputError, match="float32 samples"):
        read_rgb(tmp_path / "f.tiff")


# --- depth ---------------------------------------------------------------------------------------

def test_depth_png16_with_scale(tmp_path):
    mm = rng_image((H, W), np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), mm)
    d = read_depth(tmp_path / "d.png", depth_scale=0.001)
    assert d.dtype == np.float32 and d.shape == (H, W)
    np.testing.assert_allclose(d, mm.astype(np.float32) * np.float32(0.001), rtol=1e-7)
    np.testing.assert_array_equal(read_depth(tmp_path / "d.png"), mm.astype(np.float32))


def test_depth_png8_and_grey_as_rgb(tmp_path):
    d8 = rng_image((H, W), np.uint8)
    cv2.imwrite(str(tmp_path / "d.png"), d8)
    np.testing.assert_array_equal(read_depth(tmp_path / "d.png"), d8.astype(np.float32))
    cv2.imwrite(str(tmp_path / "rgb.png"), np.repeat(d8[:, :, None], 3, 2))
    np.testing.assert_array_equal(read_depth(tmp_path / "rgb.png"), d8.astype(np.float32))
    cv2.imwrite(str(tmp_path / "cmap.png"), cv2.applyColorMap(d8, cv2.COLORMAP_JET))
    with pytest.raises(InputError, match=r"cmap\.png: depth image has 3 different colour channels"):
        read_depth(tmp_path / "cmap.png")


@pytest.mark.parametrize("shape", [(H, W), (H, W, 1), (1, H, W)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.float16, np.uint16])
def test_depth_npy(tmp_path, shape, dtype):
    d = (np.random.default_rng(0).uniform(0, 50, (H, W))).astype(dtype)
    np.save(tmp_path / "d.npy", d.reshape(shape))
    out = read_depth(tmp_path / "d.npy")
    assert out.dtype == np.float32 and out.shape == (H, W)
    np.testing.assert_array_equal(out, d.astype(np.float32))
    assert image_size(tmp_path / "d.npy") == (H, W)


def test_depth_npy_errors(tmp_path):
    np.save(tmp_path / "s.npy", np.zeros((2, H, W)))
    with pytest.raises(InputError, match=r"s\.npy: depth array has shape \(2, 9, 13\)"):
        read_depth(tmp_path / "s.npy")
    np.save(tmp_path / "b.npy", np.zeros((H, W), bool))
    with pytest.raises(InputError, match="dtype bool"):
        read_depth(tmp_path / "b.npy")
    np.save(tmp_path / "o.npy", np.array([{"a": 1}], dtype=object))
    with pytest.raises(InputError, match=r"o\.npy"):
        read_depth(tmp_path / "o.npy")
    (tmp_path / "x.npy").write_bytes(b"garbage")
    with pytest.raises(InputError, match=r"x\.npy: not a valid \.npy file"):
        read_depth(tmp_path / "x.npy")
    with pytest.raises(InputError, match=r"x\.npy: not a valid \.npy file"):
        image_size(tmp_path / "x.npy")


@pytest.mark.parametrize("ext", [".tiff", ".tif"])
def test_depth_tiff_float32(tmp_path, ext):
    d = np.random.default_rng(1).uniform(0.5, 20.0, (H, W)).astype(np.float32)
    assert cv2.imwrite(str(tmp_path / f"d{ext}"), d)
    np.testing.assert_array_equal(read_depth(tmp_path / f"d{ext}"), d)
    assert image_size(tmp_path / f"d{ext}") == (H, W)


def test_depth_non_finite_is_no_coverage_and_negative_is_an_error(tmp_path):
    d = np.full((H, W), 2.0, np.float32)
    d[0, 0], d[0, 1], d[0, 2] = np.inf, np.nan, -np.inf
    np.save(tmp_path / "d.npy", d)
    out = read_depth(tmp_path / "d.npy", depth_scale=2.0)
    assert out[0, :3].tolist() == [0.0, 0.0, 0.0] and out[1, 1] == 4.0
    d[3, 3] = -0.5
    np.save(tmp_path / "n.npy", d)
    with pytest.raises(InputError, match=r"n\.npy: depth has negative values \(min -0\.5\)"):
        read_depth(tmp_path / "n.npy")


def test_depth_unknown_extension(tmp_path):
    (tmp_path / "d.jpg").write_bytes(b"")
    with pytest.raises(InputError, match=r"d\.jpg: unknown depth format '\.jpg'"):
        read_depth(tmp_path / "d.jpg")


# --- EXR (fixtures written by the official OpenEXR library: tests/data/exr/make_fixtures.py) -----

EXPECTED = np.load(EXR_DIR / "expected.npz")
SUPPORTED = ["z_float_none.exr", "z_float_rle.exr", "z_float_zips.exr", "z_float_zip.exr", "z_half_zip.exr",
             "z_half_rle.exr", "z_float_zip_noise.exr", "z_uint_zips.exr", "rgb_half_zip.exr", "rg_float_zip.exr"]


@pytest.mark.parametrize("name", SUPPORTED)
def test_exr_reader_matches_openexr(name):
    channels = read_exr(EXR_DIR / name)
    expected = {k.split(":", 1)[1]: v for k, v in EXPECTED.items() if k.split(":", 1)[0] == name}
    assert sorted(channels) == sorted(expected)
    for ch, values in expected.items():
        assert channels[ch].dtype == np.float32
        np.testing.assert_array_equal(channels[ch], values.astype(np.float32))
    info = read_exr_info(EXR_DIR / name)
    assert (info.height, info.width) == (23, 37) and set(info.channels) == set(expected)


@pytest.mark.parametrize("name, channel", [("z_float_zip.exr", "Z"), ("z_half_zip.exr", "Z"),
                                           ("rgb_half_zip.exr", "R"), ("z_float_rle.exr", "Z")])
def test_depth_exr(name, channel):
    expected = EXPECTED[f"{name}:{channel}"].astype(np.float32)
    np.testing.assert_array_equal(read_depth(EXR_DIR / name), expected)
    np.testing.assert_array_equal(read_depth(EXR_DIR / name, depth_scale=0.5), expected * np.float32(0.5))
    assert image_size(EXR_DIR / name) == (23, 37)


def test_depth_exr_ambiguous_channels():
    with pytest.raises(InputError, match=r"rg_float_zip\.exr: EXR file has channels G, R and none is named Z"):
        read_depth(EXR_DIR / "rg_float_zip.exr")


def test_depth_exr_unsupported_compression_says_how_to_fix():
    with pytest.raises(UnsupportedExrError, match="PIZ"):
        read_exr(EXR_DIR / "z_float_piz.exr")
    try:
        d = read_depth(EXR_DIR / "z_float_piz.exr")
    except InputError as e:
        msg = str(e)
        assert "z_float_piz.exr" in msg and "compression PIZ is not supported" in msg
        assert "OPENCV_IO_ENABLE_OPENEXR=1" in msg and ".npy" in msg
    else:  # an OpenCV build with OpenEXR read it
        np.testing.assert_allclose(d, EXPECTED["z_float_piz.exr:Z"], rtol=0, atol=0)


def test_opencv_exr_switch_is_set_on_import():
    assert os.environ.get("OPENCV_IO_ENABLE_OPENEXR") is not None


def test_exr_corrupt_files(tmp_path):
    data = (EXR_DIR / "z_float_zip.exr").read_bytes()
    (tmp_path / "cut.exr").write_bytes(data[: len(data) - 100])
    with pytest.raises(InputError, match=r"cut\.exr: (truncated|corrupt) EXR file"):
        read_exr(tmp_path / "cut.exr")
    (tmp_path / "head.exr").write_bytes(data[:60])
    with pytest.raises(InputError, match=r"head\.exr: truncated EXR header"):
        read_exr_info(tmp_path / "head.exr")
    (tmp_path / "magic.exr").write_bytes(b"P" + data[1:])
    with pytest.raises(InputError, match="not an OpenEXR file"):
        read_depth(tmp_path / "magic.exr")
    tiled = bytearray(data)
    tiled[5] |= 0x02  # version flags: bit 9 = tiled
    (tmp_path / "tiled.exr").write_bytes(bytes(tiled))
    with pytest.raises(UnsupportedExrError, match="tiled EXR files are not supported"):
        read_exr(tmp_path / "tiled.exr")


# --- headers ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, params", [
    ("a.png", []), ("a.jpg", []), ("p.jpg", [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]), ("a.tiff", []), ("a.bmp", []),
])
def test_image_size_from_headers(tmp_path, name, params):
    img = rng_image((H, W, 3), np.uint8)
    assert cv2.imwrite(str(tmp_path / name), img, params)
    assert image_size(tmp_path / name) == (H, W)


def test_image_size_errors(tmp_path):
    (tmp_path / "t.png").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00")
    with pytest.raises(InputError, match=r"t\.png: malformed PNG header"):
        image_size(tmp_path / "t.png")
    (tmp_path / "z.png").write_bytes(b"")
    with pytest.raises(InputError, match=r"z\.png: cannot decode image"):
        image_size(tmp_path / "z.png")


# --- RendersReader ---------------------------------------------------------------------------------

def make_folder(root: Path, views=("b", "a", "c")) -> Path:
    for i, v in enumerate(views):
        (root / "rgb").mkdir(parents=True, exist_ok=True)
        (root / "depth").mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / "rgb" / f"{v}.png"), rng_image((H, W, 3), np.uint8, seed=i))
        cv2.imwrite(str(root / "depth" / f"{v}.png"), rng_image((H, W), np.uint16, seed=i))
    return root


def test_reader(tmp_path):
    root = make_folder(tmp_path / "r")
    (root / "rgb" / "notes.txt").write_text("ignored")
    (root / "rgb" / ".hidden.png").write_bytes(b"ignored")
    reader = RendersReader.from_dirs(root / "rgb", root / "depth", depth_scale=0.001)
    assert reader.views() == ["a", "b", "c"] and reader.depth_views() == ["a", "b", "c"] and reader.has_depth
    rgb, depth = reader.rgb("b"), reader.depth("b")
    assert rgb.shape == (H, W, 3) and depth.shape == (H, W) and reader.size("b") == (H, W)
    np.testing.assert_array_equal(rgb, read_rgb(root / "rgb" / "b.png"))
    np.testing.assert_allclose(depth, rng_image((H, W), np.uint16, seed=0) * np.float32(0.001), rtol=1e-7)
    assert reader.rgb_path("c") == root / "rgb" / "c.png" and reader.depth_path("c") == root / "depth" / "c.png"
    assert "views=3" in repr(reader)


def test_reader_from_a_source_spec(tmp_path):
    from r360gpu.bundle import SourceSpec

    root = make_folder(tmp_path / "r")
    spec = SourceSpec("renders", root, 2.0, root / "rgb", None)
    reader = spec.reader()
    assert reader.views() == ["a", "b", "c"] and not reader.has_depth and reader.depth_views() == []
    with pytest.raises(InputError, match="no depth folder"):
        reader.depth("a")
    with pytest.raises(ValueError):
        SourceSpec("scene", root / "x.ply").reader()


def test_reader_errors(tmp_path):
    root = make_folder(tmp_path / "r")
    cv2.imwrite(str(root / "rgb" / "a.jpg"), rng_image((H, W, 3), np.uint8))
    reader = RendersReader.from_dirs(root / "rgb", root / "depth")
    with pytest.raises(InputError, match=r"rgb: several RGB images for view 'a': a\.jpg, a\.png"):
        reader.rgb("a")
    with pytest.raises(InputError, match=r"depth: no depth image for view 'zz' \(looked for zz\.png, zz\.exr"):
        reader.depth("zz")
    with pytest.raises(InputError, match=r"nowhere: RGB folder does not exist"):
        RendersReader.from_dirs(tmp_path / "nowhere")
    with pytest.raises(InputError, match=r"depth folder does not exist"):
        RendersReader.from_dirs(root / "rgb", tmp_path / "nodepth")
    for bad in (0, -1.0, float("nan"), float("inf")):
        with pytest.raises(InputError, match="depth_scale must be a positive number"):
            RendersReader.from_dirs(root / "rgb", depth_scale=bad)
