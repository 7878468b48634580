"""FID and KID (r360gpu.metrics.fid) against plain numpy re-statements of their definitions.

The FID reference takes tr sqrt(S1 S2) from the eigenvalues of S1 S2 (the sum of their
principal square roots' real parts) instead of a matrix square root, so it shares no code
path with the module's ``scipy.linalg.sqrtm``; the KID reference writes the unbiased MMD^2
as explicit sums over index pairs.  pytorch-fid's singular-product and imaginary-component
branches are driven by a stand-in ``sqrtm``.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.metrics import fid as F


def ref_fid(a, b, eps=0.0):
    """pytorch-fid's formula with tr(sqrtm) from eigenvalues; eps > 0: the offset branch."""
    mu1, mu2 = a.mean(0), b.mean(0)
    s1 = np.cov(a, rowvar=False) + eps * np.eye(a.shape[1])
    s2 = np.cov(b, rowvar=False) + eps * np.eye(a.shape[1])
    lam = np.linalg.eigvals(s1 @ s2).astype(complex)
    tr = float(np.sum(np.sqrt(lam).real))
    d = mu1 - mu2
    # The offset enters the covariances only inside the square root in pytorch-fid.
    return float(d @ d + np.trace(s1) + np.trace(s2) - 2 * eps * a.shape[1] - 2 * tr)


def ref_mmd2(x, y, degree=3, gamma=None, coef=1.0):
    m, d = x.shape
    g = 1.0 / d if gamma is None else gamma
    k = lambda u, v: (g * float(u @ v) + coef) ** degree  # noqa: E731
    sxx = sum(k(x[i], x[j]) for i in range(m) for j in range(m) if i != j)
    syy = sum(k(y[i], y[j]) for i in range(m) for j in range(m) if i != j)
    sxy = sum(k(x[i], y[j]) for i in range(m) for j in range(m))
    return sxx / (m * (m - 1)) + syy / (m * (m - 1)) - 2 * sxy / (m * m)


@pytest.mark.parametrize("n1,n2,d", [(200, 150, 8), (40, 60, 16), (12, 9, 32), (2, 3, 5)])
def test_fid_matches_the_eigenvalue_reference(n1, n2, d):
    rng = np.random.default_rng(n1 + d)
    a = rng.standard_normal((n1, d)) * rng.uniform(0.5, 2, d)
    b = rng.standard_normal((n2, d)) @ rng.standard_normal((d, d)) * 0.5 + 0.3
    r = F.fid_from_features(a, b)
    assert r.reason is None and not r.offset_added and (r.n_ref, r.n_out) == (n1, n2)
    scale = np.trace(np.cov(a, rowvar=False)) + np.trace(np.cov(b, rowvar=False))
    # Below d + 1 images the product is singular: the square roots of its rounding-level
    # eigenvalues (~sqrt(1e-16) of the scale each) bound how closely two methods can agree.
    tol = 1e-9 if min(n1, n2) > d else 1e-7
    assert r.value == pytest.approx(ref_fid(a, b), abs=tol * scale)


def test_fid_of_relu_features_with_dead_and_constant_columns():
    # Rank-deficient covariances with exact zero rows, as a random-weight network gives.
    rng = np.random.default_rng(7)
    a = np.maximum(rng.standard_normal((10, 24)), 0)
    b = np.maximum(rng.standard_normal((10, 24)) + 0.2, 0)
    a[:, :5] = 0.0
    b[:, :5] = 0.0
    a[:, 5:8] = 3.0
    b[:, 5:8] = 1.0
    r = F.fid_from_features(a, b)
    assert r.value == pytest.approx(ref_fid(a, b), abs=1e-7)
    assert r.value > 3 * 4.0  # the constant columns' means differ by 2


def test_identical_sets_give_zero_and_fid_is_symmetric():
    rng = np.random.default_rng(1)
    a = rng.standard_normal((50, 12))
    assert F.fid_from_features(a, a).value == pytest.approx(0.0, abs=1e-9)
    b = rng.standard_normal((30, 12)) + 1
    assert F.fid_from_features(a, b).value == pytest.approx(F.fid_from_features(b, a).value, rel=1e-9)
    # Fewer images than dimensions: singular covariances, still ~0 for the same set.
    c = rng.standard_normal((6, 40))
    assert F.fid_from_features(c, c).value == pytest.approx(0.0, abs=1e-7 * 2 * np.trace(np.cov(c, rowvar=False)))


def test_fewer_images_than_dimensions_is_computed_like_pytorch_fid():
    rng = np.random.default_rng(2)
    a, b = rng.standard_normal((7, 30)), rng.standard_normal((9, 30)) + 0.5
    r = F.fid_from_features(a, b)
    assert r.value == pytest.approx(ref_fid(a, b), abs=1e-7)


def test_singular_product_branch_adds_eps_and_warns(monkeypatch):
    rng = np.random.default_rng(3)
    a, b = rng.standard_normal((20, 6)), rng.standard_normal((25, 6)) + 1
    real_sqrtm = F.linalg.sqrtm
    seen = []

    def sqrtm(m):
        seen.append(m.copy())
        return np.full_like(m, np.inf) if len(seen) == 1 else real_sqrtm(m)

    monkeypatch.setattr(F.linalg, "sqrtm", sqrtm)
    with pytest.warns(R360Warning, match="singular"):
        r = F.fid_from_features(a, b, eps=1e-3, what="scene x")
    s1, s2 = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    np.testing.assert_array_equal(seen[0], s1.dot(s2))
    np.testing.assert_allclose(seen[1], (s1 + 1e-3 * np.eye(6)) @ (s2 + 1e-3 * np.eye(6)), rtol=1e-12)
    assert r.offset_added and r.value == pytest.approx(ref_fid(a, b, eps=1e-3), rel=1e-9)


@pytest.mark.parametrize("imag,computed", [(5e-4, True), (5e-3, False)])
def test_imaginary_component_branch(monkeypatch, imag, computed):
    rng = np.random.default_rng(4)
    a, b = rng.standard_normal((20, 4)), rng.standard_normal((20, 4))
    real_sqrtm = F.linalg.sqrtm
    monkeypatch.setattr(F.linalg, "sqrtm", lambda m: real_sqrtm(m) + 1j * imag * np.eye(m.shape[0]))
    r = F.fid_from_features(a, b)
    if computed:  # pytorch-fid keeps the real part when the diagonal's imaginary parts are within 1e-3
        assert r.value == pytest.approx(ref_fid(a, b), rel=1e-9) and r.reason is None
    else:
        assert r.value is None and "imaginary component" in r.reason


def test_frechet_distance_from_statistics():
    rng = np.random.default_rng(5)
    a, b = rng.standard_normal((30, 5)), rng.standard_normal((40, 5))
    r = F.frechet_distance(*F.feature_statistics(a), *F.feature_statistics(b))
    assert r.value == pytest.approx(F.fid_from_features(a, b).value, rel=1e-12)
    assert r.n_ref is None
    with pytest.raises(InputError, match="different sizes"):
        F.frechet_distance(np.zeros(3), np.eye(3), np.zeros(4), np.eye(4))


def test_bad_features_are_refused():
    good = np.zeros((5, 4))
    for bad, msg in [
        (np.zeros((1, 4)), "at least 2 images"),
        (np.zeros(4), r"\(N, d\)"),
        (np.full((3, 4), np.nan), "NaN"),
        (np.array([[np.inf, 0, 0, 0], [0, 0, 0, 0]]), "infinite"),
        (np.zeros((3, 5)), "dimensions"),
        (np.array([["a"] * 4] * 3), "real numbers"),
    ]:
        with pytest.raises(InputError, match=msg):
            F.fid_from_features(good, bad)
        with pytest.raises(InputError, match=msg):
            F.kid_from_features(good, bad)


@pytest.mark.parametrize("degree,gamma,coef", [(3, None, 1.0), (2, 0.3, 0.5)])
def test_mmd2_matches_the_pairwise_sums(degree, gamma, coef):
    rng = np.random.default_rng(degree)
    x, y = rng.standard_normal((7, 5)), rng.standard_normal((7, 5)) + 0.4
    got = F.polynomial_mmd2(x, y, degree, gamma, coef)
    assert got == pytest.approx(ref_mmd2(x, y, degree, gamma, coef), rel=1e-12)


def test_kid_subsets_are_seeded_draws_without_replacement():
    rng = np.random.default_rng(8)
    a, b = rng.standard_normal((15, 6)), rng.standard_normal((11, 6)) + 0.3
    k = F.kid_from_features(a, b, subsets=4, subset_size=5, seed=3)
    draw = np.random.default_rng(3)
    vals = []
    for _ in range(4):
        ia, ib = draw.choice(15, 5, replace=False), draw.choice(11, 5, replace=False)
        vals.append(ref_mmd2(a[ia], b[ib]))
    assert (k.subsets, k.subset_size) == (4, 5)
    assert k.mean == pytest.approx(np.mean(vals), rel=1e-10)
    assert k.std == pytest.approx(np.std(vals), rel=1e-9)  # torchmetrics: std(unbiased=False)
    assert F.kid_from_features(a, b, subsets=4, subset_size=5, seed=3) == k


def test_kid_subset_size_is_capped_at_the_smaller_set():
    rng = np.random.default_rng(9)
    a, b = rng.standard_normal((6, 4)), rng.standard_normal((6, 4)) - 0.2
    k = F.kid_from_features(a, b, subsets=3)
    # Every subset holds all rows: the full unbiased MMD^2, the same in every subset.
    assert k.subset_size == 6
    assert k.mean == pytest.approx(ref_mmd2(a, b), rel=1e-10)
    assert k.std == pytest.approx(0.0, abs=1e-12)
    one = F.kid_from_features(a, b, subsets=1)
    assert one.std == 0.0 and one.mean == pytest.approx(k.mean, rel=1e-12)


def test_kid_is_near_zero_for_one_distribution_and_bad_arguments_refused():
    rng = np.random.default_rng(10)
    a, b = rng.standard_normal((400, 8)), rng.standard_normal((400, 8))
    same = F.kid_from_features(a, b, subsets=20, subset_size=100)
    shifted = F.kid_from_features(a, b + 0.5, subsets=20, subset_size=100)
    assert abs(same.mean) < 0.1 * shifted.mean
    # The unbiased estimator of a set against itself is not 0 (its pairs are not independent):
    # the k(x_i, x_i) terms count in the cross sum only.
    assert F.kid_from_features(a[:30], a[:30], subsets=2).mean == pytest.approx(ref_mmd2(a[:30], a[:30]), rel=1e-10)
    with pytest.raises(InputError, match="subset"):
        F.kid_from_features(a, a, subsets=0)
    with pytest.raises(InputError, match="subsets of at least 2"):
        F.kid_from_features(a, a, subset_size=1)
    with pytest.raises(InputError, match="gamma"):
        F.kid_from_features(a, a, gamma=-1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert math.isfinite(F.kid_from_features(a[:2], a[2:4]).mean)


def test_fid_image_files_are_pytorch_fids_listing(tmp_path):
    for name in ["b.png", "a.jpg", "c.JPG", "d.webp", "e.txt", "f.jpeg", "g.png.bak", "h.tiff"]:
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "sub.png").mkdir()  # pytorch-fid's glob lists it, then fails to open it
    got = [p.name for p in F.fid_image_files(tmp_path)]
    assert got == ["a.jpg", "b.png", "d.webp", "f.jpeg", "h.tiff"]
    with pytest.raises(InputError, match="not found"):
        F.fid_image_files(tmp_path / "none")
