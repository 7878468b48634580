"""INRIA 3DGS .ply reader/writer and the PLY container parser."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.io.inria_ply import load_inria_ply, save_ply
from r360gpu.io.ply import read_ply, read_ply_header

BASE = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def _write(path, props, rows, fmt="binary_little_endian", types=None, extra_header="", tail=b""):
    """A PLY file written by hand (independent of r360gpu's writer)."""
    types = types or {}
    endian = {"binary_little_endian": "<", "binary_big_endian": ">", "ascii": "<"}[fmt]
    np_types = {"float": "f4", "double": "f8", "uchar": "u1", "int": "i4", "short": "i2"}
    header = ["ply", f"format {fmt} 1.0", "comment hand-made", extra_header.rstrip("\n"),
              f"element vertex {len(rows)}"]
    header += [f"property {types.get(p, 'float')} {p}" for p in props]
    header.append("end_header")
    text = "\n".join(h for h in header if h) + "\n"
    dt = np.dtype([(p, endian + np_types[types.get(p, "float")]) for p in props])
    arr = np.array([tuple(r) for r in rows], dtype=dt)
    if fmt == "ascii":
        body = "".join(" ".join(repr(float(v)) if types.get(p, "float") in ("float", "double") else str(int(v))
                                for p, v in zip(props, r)) + "\n" for r in rows).encode()
    else:
        body = arr.tobytes()
    path.write_bytes(text.encode() + body + tail)
    return path


def _row(x=0.0, dc=(0.0, 0.0, 0.0), opacity=0.0, log_scale=(0.0, 0.0, 0.0), rot=(1.0, 0.0, 0.0, 0.0)):
    return [x, 2.0, 3.0, *dc, opacity, *log_scale, *rot]


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
def test_hand_made_file_decodes_by_the_documented_rules(tmp_path, fmt):
    rows = [
        _row(1.0, dc=(0.5, -1.0, 2.0), opacity=0.0, log_scale=(math.log(2), 0.0, math.log(0.25)),
             rot=(2.0, 0.0, 0.0, 0.0)),
        _row(-4.0, opacity=math.log(3.0), rot=(0.0, 0.0, 0.0, -3.0)),
    ]
    g = load_inria_ply(_write(tmp_path / "a.ply", BASE, rows, fmt))
    assert g.n == 2 and g.sh_degree == 0
    np.testing.assert_allclose(g.means, [[1, 2, 3], [-4, 2, 3]])
    np.testing.assert_allclose(g.scales[0], [2.0, 1.0, 0.25], rtol=1e-6)
    np.testing.assert_allclose(g.opacities, [0.5, 0.75], rtol=1e-6)  # sigmoid(log 3) = 3/4
    np.testing.assert_allclose(g.quats, [[1, 0, 0, 0], [0, 0, 0, -1]])
    np.testing.assert_allclose(g.sh[0, 0], [0.5, -1.0, 2.0])


def test_f_rest_is_channel_major(tmp_path):
    # Degree 1: f_rest_0..2 are R's three coefficients, 3..5 G's, 6..8 B's.
    props = BASE + [f"f_rest_{i}" for i in range(9)]
    rest = [10, 11, 12, 20, 21, 22, 30, 31, 32]
    g = load_inria_ply(_write(tmp_path / "a.ply", props, [_row() + rest]))
    assert g.sh_degree == 1
    np.testing.assert_array_equal(g.sh[0, 1:], [[10, 20, 30], [11, 21, 31], [12, 22, 32]])


def test_property_types_and_order_follow_the_header(tmp_path):
    props = ["opacity"] + BASE[:6] + ["rot_0", "rot_1", "rot_2", "rot_3", "scale_0", "scale_1", "scale_2"]
    types = {"x": "double", "opacity": "double", "rot_0": "uchar", "rot_1": "short"}
    row = [0.0, 1.5, 2.0, 3.0, 0.1, 0.2, 0.3, 4, 3, 0, 0, 0.0, 0.0, 0.0]
    g = load_inria_ply(_write(tmp_path / "a.ply", props, [row], types=types))
    np.testing.assert_allclose(g.quats[0], [0.8, 0.6, 0, 0], rtol=1e-6)
    assert g.means[0, 0] == 1.5 and g.opacities[0] == 0.5


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian", "ascii"])
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_round_trip(tmp_path, fmt, degree):
    g = random_gaussians(300, degree, seed=degree)
    save_ply(tmp_path / "s.ply", g, format=fmt)
    h = load_inria_ply(tmp_path / "s.ply")
    assert h.n == g.n and h.sh_degree == degree
    np.testing.assert_array_equal(h.means, g.means)
    np.testing.assert_array_equal(h.sh, g.sh)
    # exp(log(s)) and sigmoid(logit(o)) are computed in float64 and stored in
    # float32: a few float32 ulps.
    np.testing.assert_allclose(h.scales, g.scales, rtol=3e-7)
    np.testing.assert_allclose(h.opacities, g.opacities, rtol=3e-7, atol=1e-9)
    np.testing.assert_allclose(h.quats, g.quats, atol=1e-7)


def test_writer_layout_is_inria(tmp_path):
    save_ply(tmp_path / "s.ply", random_gaussians(3, 2))
    hdr = read_ply_header(tmp_path / "s.ply")
    names = hdr.element("vertex").property_names()
    assert names[:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    assert names[9:33] == [f"f_rest_{i}" for i in range(24)]
    assert names[33:] == ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    assert hdr.format == "binary_little_endian"
    assert all(p.code == "f4" for p in hdr.element("vertex").properties)


def test_writer_clips_saturated_opacities(tmp_path):
    g = random_gaussians(2, 0)
    g = Gaussians(g.means, g.scales, g.quats, np.array([0.0, 1.0]), g.sh)
    save_ply(tmp_path / "s.ply", g)
    h = load_inria_ply(tmp_path / "s.ply")
    assert 0 < h.opacities[0] < 1e-37 and 1 - 1e-7 < h.opacities[1] < 1.0 + 1e-12


def test_extra_properties_ignored_with_one_warning(tmp_path):
    props = BASE + ["nx", "ny", "nz", "filter_3D", "semantic_id"]
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        g = load_inria_ply(_write(tmp_path / "a.ply", props, [_row() + [0, 0, 0, 1, 2]]))
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert g.n == 1 and len(msgs) == 1
    assert "filter_3D" in msgs[0] and "semantic_id" in msgs[0] and "nx" not in msgs[0]


def test_missing_required_properties(tmp_path):
    props = [p for p in BASE if p not in ("opacity", "rot_3")]
    with pytest.raises(InputError, match="opacity, rot_3") as e:
        load_inria_ply(_write(tmp_path / "a.ply", props, [[0.0] * len(props)]))
    assert "a.ply" in str(e.value)


@pytest.mark.parametrize("count", [3, 10, 44])
def test_bad_f_rest_count(tmp_path, count):
    props = BASE + [f"f_rest_{i}" for i in range(count)]
    with pytest.raises(InputError, match=f"{count} f_rest"):
        load_inria_ply(_write(tmp_path / "a.ply", props, [_row() + [0.0] * count]))


def test_f_rest_gap(tmp_path):
    props = BASE + [f"f_rest_{i}" for i in range(10) if i != 4]
    with pytest.raises(InputError, match="without gaps"):
        load_inria_ply(_write(tmp_path / "a.ply", props, [_row() + [0.0] * 9]))


def test_truncated_binary(tmp_path):
    p = _write(tmp_path / "a.ply", BASE, [_row(), _row(), _row()])
    p.write_bytes(p.read_bytes()[:-10])
    with pytest.raises(InputError, match="truncated.*3 records.*only 2"):
        load_inria_ply(p)


def test_truncated_header(tmp_path):
    p = tmp_path / "a.ply"
    p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n")
    with pytest.raises(InputError, match="end_header"):
        load_inria_ply(p)


def test_header_count_smaller_than_data(tmp_path):
    p = _write(tmp_path / "a.ply", BASE, [_row()], tail=np.zeros(14, "<f4").tobytes())
    with pytest.raises(InputError, match="wrong element count"):
        load_inria_ply(p)


def test_truncated_and_overlong_ascii(tmp_path):
    p = _write(tmp_path / "a.ply", BASE, [_row(), _row()], fmt="ascii")
    text = p.read_text()
    p.write_text(text[: text.rstrip().rfind(" ")])
    with pytest.raises(InputError, match="truncated"):
        load_inria_ply(p)
    p.write_text(text + "1 2 3\n")
    with pytest.raises(InputError, match="wrong element count"):
        load_inria_ply(p)
    p.write_text(text.replace("0.0", "abc", 1))
    with pytest.raises(InputError, match="non-numeric"):
        load_inria_ply(p)


def test_not_a_ply(tmp_path):
    p = tmp_path / "a.ply"
    p.write_bytes(b"\x00\x01garbage")
    with pytest.raises(InputError, match="not a PLY file"):
        load_inria_ply(p)
    with pytest.raises(InputError, match="cannot read"):
        load_inria_ply(tmp_path / "missing.ply")


def test_malformed_header_lines(tmp_path):
    p = tmp_path / "a.ply"
    for body, msg in [
        ("format binary_middle_endian 1.0\nelement vertex 0\nend_header\n", "unsupported PLY format"),
        ("format ascii 1.0\nproperty float x\nend_header\n", "before any element"),
        ("format ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", "unknown PLY property type"),
        ("format ascii 1.0\nelement vertex one\nend_header\n", "malformed PLY element"),
        ("element vertex 0\nend_header\n", "no 'format'"),
        ("format ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\nend_header\n", "twice"),
    ]:
        p.write_text("ply\n" + body)
        with pytest.raises(InputError, match=msg):
            read_ply(p)


def test_empty_vertex_element(tmp_path):
    with pytest.raises(InputError, match="no Gaussians"):
        load_inria_ply(_write(tmp_path / "a.ply", BASE, []))


def test_nan_and_zero_quaternion_gaussians_dropped(tmp_path):
    rows = [_row(), _row(x=float("nan")), _row(rot=(0, 0, 0, 0)), _row(log_scale=(float("inf"), 0, 0)), _row()]
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        g = load_inria_ply(_write(tmp_path / "a.ply", BASE, rows))
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert g.n == 2 and len(msgs) == 1
    assert "dropped 3 of 5" in msgs[0] and "2 with NaN/Inf" in msgs[0] and "1 with zero quaternion" in msgs[0]


def test_very_negative_log_scale_is_dropped_as_non_positive(tmp_path):
    rows = [_row(), _row(log_scale=(-200.0, 0, 0))]  # exp(-200) is 0 in float32
    with pytest.warns(R360Warning, match="1 with non-positive scale"):
        g = load_inria_ply(_write(tmp_path / "a.ply", BASE, rows))
    assert g.n == 1


def test_list_element_before_vertex_is_skipped(tmp_path):
    # A mesh-like 'face' element with a list property precedes the Gaussians.
    for fmt in ("binary_little_endian", "ascii"):
        header = ("ply\nformat %s 1.0\nelement face 2\nproperty list uchar int idx\n"
                  "element vertex 1\n" % fmt + "".join(f"property float {p}\n" for p in BASE) + "end_header\n")
        row = np.array(_row(x=7.0), "<f4")
        if fmt == "ascii":
            body = b"3 0 1 2\n2 5 6\n" + (" ".join(map(repr, row.tolist())) + "\n").encode()
        else:
            body = (bytes([3]) + np.array([0, 1, 2], "<i4").tobytes() + bytes([2])
                    + np.array([5, 6], "<i4").tobytes() + row.tobytes())
        p = tmp_path / f"m_{fmt}.ply"
        p.write_bytes(header.encode() + body)
        with pytest.warns(R360Warning, match="elements face"):
            g = load_inria_ply(p)
        assert g.means[0, 0] == 7.0


def test_no_vertex_element(tmp_path):
    p = tmp_path / "a.ply"
    p.write_text("ply\nformat ascii 1.0\nelement point 1\nproperty float x\nend_header\n1\n")
    with pytest.raises(InputError, match="no 'vertex' element"):
        load_inria_ply(p)
