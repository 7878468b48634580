"""Gaussians data type, the drop policy of build_gaussians, and the SH convention."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.io.gaussians import Gaussians, build_gaussians, random_gaussians
from r360gpu.io.sh import C0, C1, C2, C3, sh_basis, sh_coeff_count, sh_degree_from_count, sh_to_color


def _arrays(n=4, k=4):
    rng = np.random.default_rng(3)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return dict(means=rng.normal(size=(n, 3)), scales=rng.uniform(0.1, 1, (n, 3)), quats=q,
                opacities=rng.uniform(0, 1, n), sh=rng.normal(size=(n, k, 3)))


def test_constructor_converts_to_readonly_float32_contiguous():
    a = _arrays()
    src = a["means"]
    g = Gaussians(**a)
    assert g.n == 4 and len(g) == 4 and g.sh_degree == 1
    for name in ("means", "scales", "quats", "opacities", "sh"):
        arr = getattr(g, name)
        assert arr.dtype == np.float32 and arr.flags.c_contiguous and not arr.flags.writeable
    assert src.flags.writeable  # the caller's array is untouched
    f32 = np.ascontiguousarray(a["scales"], np.float32)
    g2 = Gaussians(a["means"], f32, a["quats"], a["opacities"], a["sh"])
    assert f32.flags.writeable and not g2.scales.flags.writeable


@pytest.mark.parametrize("field,value,msg", [
    ("means", np.zeros((4, 2)), "means"),
    ("quats", np.zeros((4, 3)), "quats"),
    ("opacities", np.zeros((3,)), "opacities"),
    ("sh", np.zeros((4, 5, 3)), "coefficients"),
])
def test_constructor_rejects_bad_shapes(field, value, msg):
    a = _arrays()
    a[field] = value
    with pytest.raises(ValueError, match=msg):
        Gaussians(**a)


@pytest.mark.parametrize("field,index,value,reason", [
    ("means", (1, 0), np.nan, "NaN/Inf"),
    ("sh", (2, 3, 1), np.inf, "NaN/Inf"),
    ("scales", (0, 2), 0.0, "non-positive scale"),
    ("opacities", (3,), 1.5, "opacity outside"),
    ("quats", (0, 0), 5.0, "quaternion not unit"),
])
def test_constructor_rejects_bad_values(field, index, value, reason):
    a = _arrays()
    a[field][index] = value
    with pytest.raises(ValueError, match=reason):
        Gaussians(**a)


def test_opacity_bounds_are_closed():
    a = _arrays()
    a["opacities"][:2] = [0.0, 1.0]
    assert Gaussians(**a).opacities[:2].tolist() == [0.0, 1.0]


def test_empty_set_is_valid():
    a = _arrays(n=0, k=9)
    g = Gaussians(**a)
    assert g.n == 0 and g.sh_degree == 2
    assert Gaussians.concat([g, random_gaussians(2, 1)]).n == 2


def test_subset_by_mask_and_indices():
    g = random_gaussians(10, 2, seed=1)
    mask = np.zeros(10, bool)
    mask[[1, 4, 7]] = True
    s = g.subset(mask)
    assert s.n == 3 and s.sh_degree == 2
    np.testing.assert_array_equal(s.means, g.means[[1, 4, 7]])
    t = g.subset(np.array([7, 1]))
    np.testing.assert_array_equal(t.sh, g.sh[[7, 1]])
    assert g.subset(np.zeros(10, bool)).n == 0
    with pytest.raises(ValueError):
        g.subset(np.ones(3, bool))
    with pytest.raises(ValueError):
        g.subset(np.array([0.5]))


def test_concat_pads_sh_to_highest_degree():
    a, b = random_gaussians(3, 0, seed=1), random_gaussians(2, 2, seed=2)
    c = Gaussians.concat([a, b])
    assert c.n == 5 and c.sh_degree == 2
    np.testing.assert_array_equal(c.sh[:3, 0], a.sh[:, 0])
    assert not c.sh[:3, 1:].any()
    np.testing.assert_array_equal(c.sh[3:], b.sh)
    np.testing.assert_array_equal(c.opacities, np.concatenate([a.opacities, b.opacities]))
    with pytest.raises(ValueError):
        Gaussians.concat([])


def test_with_sh_degree_truncates_and_pads():
    g = random_gaussians(4, 3, seed=5)
    assert g.with_sh_degree(1).sh.shape == (4, 4, 3)
    np.testing.assert_array_equal(g.with_sh_degree(1).sh, g.sh[:, :4])
    assert g.with_sh_degree(0).with_sh_degree(3).sh[:, 1:].sum() == 0


def test_random_gaussians_is_reproducible():
    a, b = random_gaussians(50, 3, seed=9), random_gaussians(50, 3, seed=9)
    np.testing.assert_array_equal(a.sh, b.sh)
    assert not np.array_equal(a.means, random_gaussians(50, 3, seed=10).means)


def test_build_gaussians_normalises_quaternions():
    a = _arrays()
    a["quats"] = a["quats"] * 3.0
    g = build_gaussians(**a, source="x.ply")
    np.testing.assert_allclose(np.linalg.norm(g.quats, axis=1), 1.0, atol=1e-6)


def test_build_gaussians_drops_bad_with_one_warning():
    a = _arrays(n=8)
    a["means"][0, 1] = np.nan
    a["sh"][1, 2, 0] = -np.inf
    a["quats"][2] = 0.0
    a["scales"][3, 0] = -1.0
    a["scales"][4, 0] = 1e-50  # underflows to 0 in float32
    a["means"][5, 0] = 1e300   # overflows to Inf in float32
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        g = build_gaussians(**a, source="scene.ply")
    msgs = [str(w.message) for w in rec if issubclass(w.category, R360Warning)]
    assert len(msgs) == 1
    assert "scene.ply" in msgs[0] and "dropped 6 of 8" in msgs[0]
    assert "3 with NaN/Inf" in msgs[0] and "1 with zero quaternion" in msgs[0]
    assert "2 with non-positive scale" in msgs[0]
    assert g.n == 2
    np.testing.assert_allclose(g.means, a["means"][6:].astype(np.float32))


def test_build_gaussians_huge_quaternion_is_normalised_not_dropped():
    a = _arrays(n=2)
    a["quats"][0] = [1e200, 0, 0, 1e200]
    g = build_gaussians(**a, source="s")
    np.testing.assert_allclose(g.quats[0], [math.sqrt(0.5), 0, 0, math.sqrt(0.5)], atol=1e-7)


def test_build_gaussians_all_bad_or_empty_is_input_error():
    a = _arrays(n=2)
    a["means"][:] = np.nan
    with pytest.raises(InputError, match="all 2 Gaussians are invalid") as e:
        build_gaussians(**a, source="bad.ply")
    assert "bad.ply" in str(e.value)
    b = _arrays(n=0)
    with pytest.raises(InputError, match="no Gaussians"):
        build_gaussians(**b, source="empty.ply")


# ---------------------------------------------------------------- SH convention


def test_sh_constants_closed_form():
    pi = math.pi
    assert C0 == pytest.approx(1 / (2 * math.sqrt(pi)), rel=1e-15)
    assert C1 == pytest.approx(math.sqrt(3) / (2 * math.sqrt(pi)), rel=1e-15)
    assert C2[0] == pytest.approx(math.sqrt(15) / (2 * math.sqrt(pi)), rel=1e-15)
    assert C2[2] == pytest.approx(math.sqrt(5) / (4 * math.sqrt(pi)), rel=1e-15)
    assert C2[4] == pytest.approx(math.sqrt(15) / (4 * math.sqrt(pi)), rel=1e-15)
    assert C3[1] == pytest.approx(math.sqrt(105) / (2 * math.sqrt(pi)), rel=1e-15)


def test_sh_basis_is_orthonormal_on_the_sphere():
    # Fibonacci-sphere quadrature: integral over S^2 ~ (4 pi / N) * sum.
    n = 20000
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = i * math.pi * (3 - math.sqrt(5))
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    b = sh_basis(d, 3)
    gram = (4 * math.pi / n) * b.T @ b
    np.testing.assert_allclose(gram, np.eye(16), atol=2e-3)


def test_sh_basis_signs_follow_inria_order():
    # Direction (1, 2, 2) / 3: each basis value written out from the documented table.
    x, y, z = 1 / 3, 2 / 3, 2 / 3
    xx, yy, zz = x * x, y * y, z * z
    expected = [
        C0,
        -C1 * y, C1 * z, -C1 * x,
        C2[0] * x * y, C2[1] * y * z, C2[2] * (2 * zz - xx - yy), C2[3] * x * z, C2[4] * (xx - yy),
        C3[0] * y * (3 * xx - yy), C3[1] * x * y * z, C3[2] * y * (4 * zz - xx - yy),
        C3[3] * z * (2 * zz - 3 * xx - 3 * yy), C3[4] * x * (4 * zz - xx - yy), C3[5] * z * (xx - yy),
        C3[6] * x * (xx - 3 * yy),
    ]
    got = sh_basis(np.array([[x, y, z]]), 3)[0]
    np.testing.assert_allclose(got, expected, rtol=1e-14)
    # Numerical spot values (y-odd terms are negative for y > 0 with these signs).
    assert got[1] == pytest.approx(-0.3257350079352799)
    assert got[9] == pytest.approx(-0.5900435899266435 * (2 / 3) * (3 / 9 - 4 / 9))
    np.testing.assert_array_equal(sh_basis(np.array([[x, y, z]]), 1)[0], got[:4])


def test_sh_to_color_by_hand():
    sh = np.zeros((2, 4, 3))
    sh[:, 0] = [[1.0, -2.0, 0.0], [0.0, 0.0, 0.0]]
    sh[1, 3] = [1.0, 0.0, 0.0]  # the -C1 * x basis function, red channel
    dirs = np.array([[0.0, 0.0, 5.0], [2.0, 0.0, 0.0]])  # normalised inside
    rgb = sh_to_color(sh, dirs)
    np.testing.assert_allclose(rgb[0], [C0 + 0.5, 0.0, 0.5])  # green clamps at 0
    np.testing.assert_allclose(rgb[1], [0.5 - C1, 0.5, 0.5])


def test_sh_counts():
    assert [sh_coeff_count(d) for d in range(4)] == [1, 4, 9, 16]
    assert sh_degree_from_count(9) == 2
    with pytest.raises(ValueError):
        sh_degree_from_count(5)
    with pytest.raises(ValueError):
        sh_coeff_count(4)
