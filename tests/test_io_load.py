"""The load_gaussians / load_cameras dispatchers and cross-format round trips."""
from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io import (
    Camera, load_cameras, load_gaussians, random_gaussians, save_cameras_json, save_colmap,
    save_compressed_ply, save_ply, save_splat, save_transforms_json,
)
from r360gpu.io.rotation import quat_to_rotmat
from r360gpu.io.sh import C0


def _cams(n=5, seed=0):
    rng = np.random.default_rng(seed)
    return [Camera(quat_to_rotmat(rng.normal(size=4)), rng.normal(size=3) * 2, 600.0 + 3 * i, 598.5,
                   400.25, 300.0 - i, 800, 600, f"img_{(7 * i) % n:02d}.png") for i in range(n)]


def _assert_same_cameras(a_list, b_list, atol=1e-12):
    assert [c.name for c in a_list] == [c.name for c in b_list]
    for a, b in zip(a_list, b_list):
        assert (a.width, a.height) == (b.width, b.height)
        np.testing.assert_allclose([b.fx, b.fy, b.cx, b.cy], [a.fx, a.fy, a.cx, a.cy], rtol=1e-14)
        np.testing.assert_allclose(b.R, a.R, atol=atol)
        np.testing.assert_allclose(b.t, a.t, atol=atol)


# ------------------------------------------------------------------ Gaussians


def test_dispatch_by_extension_and_content(tmp_path):
    g = random_gaussians(300, 1, seed=3)
    save_ply(tmp_path / "a.ply", g)
    save_compressed_ply(tmp_path / "b.compressed.ply", g)
    save_compressed_ply(tmp_path / "c.ply", g)          # compressed content, plain name
    save_splat(tmp_path / "d.SPLAT", g.with_sh_degree(0))
    save_ply(tmp_path / "e.data", g)                    # PLY content, unknown extension
    np.testing.assert_array_equal(load_gaussians(tmp_path / "a.ply").sh, g.sh)
    for name in ("b.compressed.ply", "c.ply"):
        h = load_gaussians(tmp_path / name)
        assert h.sh_degree == 1 and np.abs(h.opacities - g.opacities).max() <= 1 / 510 + 1e-7
    assert load_gaussians(tmp_path / "d.SPLAT").n == 300
    np.testing.assert_array_equal(load_gaussians(tmp_path / "e.data").means, g.means)


def test_cross_format_gaussians_agree_within_quantisation(tmp_path):
    g = random_gaussians(256, 0, seed=8)
    save_ply(tmp_path / "a.ply", g)
    save_compressed_ply(tmp_path / "a.compressed.ply", load_gaussians(tmp_path / "a.ply"))
    save_splat(tmp_path / "a.splat", load_gaussians(tmp_path / "a.compressed.ply"))
    h = load_gaussians(tmp_path / "a.splat")
    # Compressed (one chunk, range <= 2 per axis) then .splat (exact positions).
    assert np.abs(h.means - g.means).max() <= 2 / (2 * 1023) + 1e-6
    assert np.abs(h.opacities - g.opacities).max() <= 2 / 510 + 1e-6
    # f_dc in [-1.5, 1.5]: compressed colour range <= 3 C0 -> 3 / 510; .splat adds 1 / (510 C0).
    assert np.abs(h.sh - g.sh).max() <= 3 / 510 + 1 / (510 * C0) + 1e-5


def test_inria_output_folder_picks_highest_iteration(tmp_path):
    for it, n in ((7000, 5), (30000, 9), (500, 3)):
        d = tmp_path / "point_cloud" / f"iteration_{it}"
        d.mkdir(parents=True)
        save_ply(d / "point_cloud.ply", random_gaussians(n, 0))
    assert load_gaussians(tmp_path).n == 9
    with pytest.raises(InputError, match="not an INRIA 3DGS output folder"):
        load_gaussians(tmp_path / "point_cloud")


@pytest.mark.parametrize("name,content,msg", [
    ("scene.ksplat", b"\x00" * 64, "a splat format r360gpu does not read"),
    ("scene.xyz", b"1 2 3\n", "unknown Gaussian-splat format"),
])
def test_unknown_scene_formats(tmp_path, name, content, msg):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(InputError, match=msg) as e:
        load_gaussians(tmp_path / name)
    assert name in str(e.value)


def test_missing_scene(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_gaussians(tmp_path / "nope.ply")


# ------------------------------------------------------------------ cameras


def test_every_camera_format_round_trips_to_the_same_cameras(tmp_path):
    cams = _cams()
    expected = sorted(cams, key=lambda c: c.name)
    save_colmap(tmp_path / "bin", cams, binary=True)
    save_colmap(tmp_path / "txt", cams, binary=False)
    save_cameras_json(tmp_path / "cameras.json", cams)
    save_transforms_json(tmp_path / "transforms.json", cams)
    for src in ("bin", "txt", "cameras.json", "transforms.json", "bin/images.bin", "txt/cameras.txt"):
        _assert_same_cameras(expected, load_cameras(tmp_path / src))


def test_chained_conversions_preserve_cameras(tmp_path):
    # COLMAP text -> cameras.json -> transforms.json -> COLMAP binary.
    cams = _cams(seed=4)
    save_colmap(tmp_path / "a", cams, binary=False)
    save_cameras_json(tmp_path / "b.json", load_cameras(tmp_path / "a"))
    save_transforms_json(tmp_path / "c.json", load_cameras(tmp_path / "b.json"))
    save_colmap(tmp_path / "d", load_cameras(tmp_path / "c.json"), binary=True)
    _assert_same_cameras(sorted(cams, key=lambda c: c.name), load_cameras(tmp_path / "d"))


def test_same_point_same_pixel_in_every_format(tmp_path):
    cam = Camera(quat_to_rotmat([math.cos(0.3), 0.0, math.sin(0.3), 0.0]), [0.5, -0.2, 3.0],
                 700.0, 710.0, 320.0, 240.0, 640, 480, "view.png")
    point = cam.center + 2.0 * cam.camera_to_world[:3, 2] + [0.1, -0.05, 0.0]
    expected, _ = cam.project([point])
    save_colmap(tmp_path / "m", [cam])
    save_cameras_json(tmp_path / "cameras.json", [cam])
    save_transforms_json(tmp_path / "transforms.json", [cam])
    for src in ("m", "cameras.json", "transforms.json"):
        (got,) = load_cameras(tmp_path / src)
        np.testing.assert_allclose(got.project([point])[0], expected, atol=1e-9)


def test_folder_discovery(tmp_path):
    save_colmap(tmp_path / "scene" / "sparse" / "0", _cams())
    assert len(load_cameras(tmp_path / "scene")) == 5
    save_colmap(tmp_path / "flat" / "sparse", _cams())
    assert len(load_cameras(tmp_path / "flat")) == 5
    save_cameras_json(tmp_path / "model" / "cameras.json", _cams(3))
    assert len(load_cameras(tmp_path / "model")) == 3


def test_ambiguous_or_empty_folders(tmp_path):
    save_colmap(tmp_path / "s" / "sparse" / "0", _cams())
    save_transforms_json(tmp_path / "s" / "transforms.json", _cams())
    with pytest.raises(InputError, match="ambiguous.*sparse/0, transforms.json"):
        load_cameras(tmp_path / "s")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no cameras found"):
        load_cameras(tmp_path / "empty")
    with pytest.raises(InputError, match="no such file"):
        load_cameras(tmp_path / "missing")


def test_cameras_sorted_by_name_and_duplicates_rejected(tmp_path):
    cams = _cams()
    save_cameras_json(tmp_path / "c.json", cams)
    assert [c.name for c in load_cameras(tmp_path / "c.json")] == sorted(c.name for c in cams)
    dup = [cams[0], cams[1], Camera(cams[2].R, cams[2].t, 1, 1, 0, 0, 2, 2, cams[0].name)]
    save_cameras_json(tmp_path / "d.json", dup)
    with pytest.raises(InputError, match=f"duplicate camera names: '{cams[0].name}'"):
        load_cameras(tmp_path / "d.json")


def test_unknown_camera_files(tmp_path):
    (tmp_path / "x.json").write_text('{"cameras": []}')
    with pytest.raises(InputError, match="neither an INRIA cameras.json"):
        load_cameras(tmp_path / "x.json")
    (tmp_path / "poses.csv").write_text("1,2,3\n")
    with pytest.raises(InputError, match="unknown camera format"):
        load_cameras(tmp_path / "poses.csv")
