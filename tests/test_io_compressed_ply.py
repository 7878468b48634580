"""PlayCanvas/SuperSplat .compressed.ply reader and writer."""
from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.compressed_ply import CHUNK_SIZE, load_compressed_ply, save_compressed_ply
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.io.ply import read_ply_header
from r360gpu.io.sh import C0

BOUNDS = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
          "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z"]
COLOUR = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
PACKED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]


def _write(path, chunks, verts, sh=None, chunk_props=BOUNDS + COLOUR, vert_type="uint",
           sh_type="uchar", n_chunks=None, n_sh=None):
    """A compressed PLY written by hand (independent of r360gpu's writer)."""
    lines = ["ply", "format binary_little_endian 1.0",
             f"element chunk {len(chunks) if n_chunks is None else n_chunks}"]
    lines += [f"property float {p}" for p in chunk_props]
    lines += [f"element vertex {len(verts)}"] + [f"property {vert_type} {p}" for p in PACKED]
    body = np.asarray(chunks, "<f4").tobytes() + np.asarray(verts, "<u4").tobytes()
    if sh is not None:
        sh = np.asarray(sh, np.uint8)
        lines += [f"element sh {len(sh) if n_sh is None else n_sh}"]
        lines += [f"property {sh_type} f_rest_{i}" for i in range(sh.shape[1])]
        body += sh.tobytes()
    lines.append("end_header")
    path.write_bytes(("\n".join(lines) + "\n").encode() + body)
    return path


def _pos(x, y, z):
    return (x << 21) | (y << 11) | z


def _rgba(r, g, b, a):
    return (r << 24) | (g << 16) | (b << 8) | a


def test_hand_packed_gaussian_decodes_by_the_documented_rules(tmp_path):
    chunk = [-1, 2, -7, 3, 5, -6,                      # position bounds
             math.log(0.5), math.log(0.5), math.log(0.5), math.log(2), math.log(2), math.log(2),
             0, 0, 0.2, 1, 1, 0.6]                     # colour bounds
    # Rotation: index of the largest component 1 (x); w, y, z stored as 10-bit fractions.
    fw, fy, fz = 873, 511, 150
    rot = (1 << 30) | (fw << 20) | (fy << 10) | fz
    vert = [_pos(2047, 0, 1023), rot, _pos(0, 1023, 2047), _rgba(255, 0, 128, 51)]
    g = load_compressed_ply(_write(tmp_path / "a.compressed.ply", [chunk], [vert]))
    assert g.n == 1 and g.sh_degree == 0
    np.testing.assert_allclose(g.means[0], [3, 2, -7 + 1023 / 2047], rtol=1e-6)
    np.testing.assert_allclose(g.scales[0], [0.5, 2, 2], rtol=1e-6)
    np.testing.assert_allclose(g.sh[0, 0], [0.5 / C0, -0.5 / C0, (0.2 + 0.4 * 128 / 255 - 0.5) / C0], rtol=1e-6)
    np.testing.assert_allclose(g.opacities[0], 0.2, rtol=1e-6)
    small = [(f / 1023 - 0.5) * math.sqrt(2) for f in (fw, fy, fz)]
    q = np.array([small[0], math.sqrt(1 - sum(v * v for v in small)), small[1], small[2]])
    np.testing.assert_allclose(g.quats[0], q / np.linalg.norm(q), atol=1e-7)


def test_chunk_without_colour_bounds_and_with_sh(tmp_path):
    chunk = [0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0]
    identity = (512 << 20) | (512 << 10) | 512  # largest is w; x, y, z ~ 0
    vert = [_pos(0, 0, 0), identity, 0, _rgba(0, 255, 51, 255)]
    sh = [[0, 255, 127, 128, 1, 2, 3, 4, 5]]  # degree 1, channel-major
    g = load_compressed_ply(_write(tmp_path / "a.ply", [chunk], [vert], sh=sh, chunk_props=BOUNDS))
    np.testing.assert_allclose(g.sh[0, 0], [-0.5 / C0, 0.5 / C0, (0.2 - 0.5) / C0], rtol=1e-6)
    assert g.opacities[0] == 1.0
    np.testing.assert_allclose(g.quats[0], [1, 0, 0, 0], atol=2e-3)
    # The PlayCanvas engine's decoder (gsplat-compressed-data.js): q * (8 / 255) - 4.
    decoded = [q * (8 / 255) - 4 for q in (0, 255, 127, 128, 1, 2, 3, 4, 5)]
    np.testing.assert_allclose(g.sh[0, 1:], np.array(decoded).reshape(3, 3).T, rtol=1e-6)


def _chunk_range(values: np.ndarray) -> np.ndarray:
    """Per-Gaussian range (max - min) of ``values`` over its chunk of 256."""
    n = len(values)
    out = np.empty_like(values, dtype=np.float64)
    for start in range(0, n, CHUNK_SIZE):
        block = values[start:start + CHUNK_SIZE].astype(np.float64)
        out[start:start + CHUNK_SIZE] = block.max(0) - block.min(0)
    return out


def test_round_trip_within_documented_bounds(tmp_path):
    g = random_gaussians(700, 3, seed=4)  # 3 chunks, the last one partial
    save_compressed_ply(tmp_path / "s.compressed.ply", g)
    h = load_compressed_ply(tmp_path / "s.compressed.ply")
    assert h.n == g.n and h.sh_degree == 3
    levels = np.array([2047, 1023, 2047])
    slack = 1e-6  # float32 storage of values and chunk bounds

    pos_bound = _chunk_range(g.means) / (2 * levels) + slack * (1 + np.abs(g.means))
    assert (np.abs(h.means - g.means) <= pos_bound).all()

    log_s, log_h = np.log(g.scales.astype(np.float64)), np.log(h.scales.astype(np.float64))
    assert (np.abs(log_h - log_s) <= _chunk_range(log_s) / (2 * levels) + slack * 10).all()

    colour = 0.5 + C0 * g.sh[:, 0].astype(np.float64)
    dc_bound = _chunk_range(colour) / (2 * 255 * C0) + slack * 10
    assert (np.abs(h.sh[:, 0] - g.sh[:, 0]) <= dc_bound).all()

    assert np.abs(h.opacities - g.opacities).max() <= 1 / 510 + slack

    sign = np.sign(np.sum(h.quats * g.quats, axis=1, dtype=np.float64))[:, None]
    delta = math.sqrt(2) / (2 * 1023)
    assert np.linalg.norm(h.quats * sign - g.quats, axis=1).max() <= 4 * math.sqrt(3) * delta

    # random_gaussians keeps f_rest in [-0.3, 0.3]: half a step of 8/255.
    assert np.abs(h.sh[:, 1:] - g.sh[:, 1:]).max() <= 4 / 255 + slack


def test_sh_rest_end_bins_and_clipping(tmp_path):
    g = random_gaussians(9, 1, seed=2)
    sh = np.array(g.sh)
    values = np.array([-6.0, -4.0, -3.99, -3.9, 0.0, 3.9, 3.99, 3.999, 7.0])
    sh[:, 1, 0] = values
    g = Gaussians(g.means, g.scales, g.quats, g.opacities, sh)
    save_compressed_ply(tmp_path / "s.ply", g)
    got = load_compressed_ply(tmp_path / "s.ply").sh[:, 1, 0]
    expect_bound = 4 / 255 + 1e-6
    inside = np.abs(values) <= 4
    assert (np.abs(got - values)[inside] <= expect_bound).all()
    np.testing.assert_array_equal(got[~inside], [-4.0, 4.0])


def test_writer_layout(tmp_path):
    save_compressed_ply(tmp_path / "s.ply", random_gaussians(257, 2))
    hdr = read_ply_header(tmp_path / "s.ply")
    assert [(e.name, e.count) for e in hdr.elements] == [("chunk", 2), ("vertex", 257), ("sh", 257)]
    assert hdr.element("chunk").property_names() == BOUNDS + COLOUR
    assert hdr.element("vertex").property_names() == PACKED
    assert all(p.code == "u1" for p in hdr.element("sh").properties)
    assert len(hdr.element("sh").properties) == 24
    save_compressed_ply(tmp_path / "d0.ply", random_gaussians(3, 0))
    assert read_ply_header(tmp_path / "d0.ply").element("sh") is None


def test_constant_chunk_decodes_exactly(tmp_path):
    g = random_gaussians(1, 0, seed=3)
    g = Gaussians.concat([g, g, g])
    save_compressed_ply(tmp_path / "s.ply", g)
    h = load_compressed_ply(tmp_path / "s.ply")
    np.testing.assert_array_equal(h.means, g.means)
    np.testing.assert_allclose(h.scales, g.scales, rtol=1e-6)


CHUNK = [0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1]
VERT = [0, 0, 0, 0xFFFFFFFF]


def test_wrong_chunk_count(tmp_path):
    p = _write(tmp_path / "a.ply", [CHUNK, CHUNK], [VERT] * 3)
    with pytest.raises(InputError, match="3 vertices need 1 chunks"):
        load_compressed_ply(p)


def test_sh_errors(tmp_path):
    with pytest.raises(InputError, match="3 vertices but 2 sh"):
        load_compressed_ply(_write(tmp_path / "a.ply", [CHUNK], [VERT] * 3, sh=np.zeros((2, 9))))
    with pytest.raises(InputError, match="must be uchar"):
        load_compressed_ply(_write(tmp_path / "b.ply", [CHUNK], [VERT], sh=np.zeros((1, 9)), sh_type="char"))
    with pytest.raises(InputError, match="M = 9, 24 or 45"):
        load_compressed_ply(_write(tmp_path / "c.ply", [CHUNK], [VERT], sh=np.zeros((1, 10))))


def test_missing_or_partial_properties(tmp_path):
    with pytest.raises(InputError, match="missing properties: min_x"):
        load_compressed_ply(_write(tmp_path / "a.ply", [CHUNK[1:]], [VERT], chunk_props=(BOUNDS + COLOUR)[1:]))
    with pytest.raises(InputError, match="only some of"):
        load_compressed_ply(_write(tmp_path / "b.ply", [CHUNK[:13]], [VERT], chunk_props=(BOUNDS + COLOUR)[:13]))


def test_packed_fields_must_be_32_bit_integers(tmp_path):
    p = _write(tmp_path / "a.ply", [CHUNK], [VERT], vert_type="float")
    with pytest.raises(InputError, match="32-bit integer"):
        load_compressed_ply(p)


def test_truncated(tmp_path):
    p = _write(tmp_path / "a.ply", [CHUNK], [VERT] * 5)
    p.write_bytes(p.read_bytes()[:-3])
    with pytest.raises(InputError, match="truncated"):
        load_compressed_ply(p)


def test_nan_bounds_drop_their_gaussians(tmp_path):
    bad = list(CHUNK)
    bad[0] = float("nan")
    p = _write(tmp_path / "a.ply", [bad, CHUNK], [VERT] * 300)
    with pytest.warns(R360Warning, match="dropped 256 of 300"):
        g = load_compressed_ply(p)
    assert g.n == 44


def test_sh_bytes_decode_like_the_playcanvas_engine(tmp_path):
    # Every byte value, against the reference decoder's rule evaluated in float64
    # (playcanvas/engine src/scene/gsplat/gsplat-compressed-data.js: q * (8 / 255) - 4).
    q = np.arange(256, dtype=np.uint8)
    n = 256
    sh = np.zeros((n, 9), np.uint8)
    sh[:, 0] = q
    sh[:, 4] = q[::-1]
    identity = (512 << 20) | (512 << 10) | 512
    chunk = [0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0]
    verts = [[_pos(0, 0, 0), identity, 0, _rgba(128, 128, 128, 255)]] * n
    g = load_compressed_ply(_write(tmp_path / "q.ply", [chunk], verts, sh=sh, chunk_props=BOUNDS))
    expect = q.astype(np.float64) * 8.0 / 255.0 - 4.0
    got = np.asarray(g.sh, np.float64)
    # f_rest_0 is coefficient 1 of red; f_rest_4 coefficient 2 of green (channel-major, 3 per channel).
    assert np.abs(got[:, 1, 0] - expect).max() <= 4e-7 * 4  # float32 storage of the decoded value
    assert np.abs(got[:, 2, 1] - expect[::-1]).max() <= 4e-7 * 4
    assert got[0, 1, 0] == -4.0 and got[255, 1, 0] == 4.0
    assert np.abs(got[:, 1, 0] - np.float32(expect)).max() == 0.0
