"""Rows are the file's rows: indices a user gives ([target].indices), the ``top`` residual indices and
the residual PLY's vertices refer to the rows of the file as written, even when the loader dropped
invalid rows (NaN), and a residual PLY keeps the file's own vertex properties."""
from __future__ import annotations

import shutil
import warnings

import numpy as np
import pytest
from numpy.lib import recfunctions

from r360gpu.bundle import load_bundle
from r360gpu.errors import R360Warning
from r360gpu.io import load_gaussians
from r360gpu.io.ply import read_ply, write_ply
from r360gpu.lift.residuals import write_residual_ply
from r360gpu.lift.target import target_from_box, target_from_indices
from r360gpu.synthetic import generate_benchmark, make_scene

ARGS = dict(seed=0, n_views=4, width=64, height=48, detail=0.25)
N_NAN = 600


@pytest.fixture(scope="module")
def bench(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("rows")
    return generate_benchmark(root, scenes=("room",), methods=("floaters",), ctx=ctx, **ARGS)[0]


def with_bad_rows(src, dst, where, extra=None):
    """``src`` PLY rewritten to ``dst`` with one NaN row inserted before each of the rows ``where``
    (indices into src's rows), and an extra vertex property ``my_label`` = ``extra`` when given."""
    vert = read_ply(src).arrays["vertex"]
    bad = vert[np.zeros(len(where), np.int64)].copy()
    bad["x"] = np.nan
    out = np.insert(vert, np.asarray(where), bad)
    if extra is not None:
        out = recfunctions.append_fields(out, "my_label", extra(len(out)), dtypes="<i4", usemask=False)
    write_ply(dst, [("vertex", out)])
    return dst


def test_nan_rows_before_the_target_do_not_shift_it(bench, tmp_path):
    scene = make_scene("room", n_views=ARGS["n_views"], width=64, height=48, detail=ARGS["detail"])
    target = np.arange(scene.background.n, scene.pre.n)  # the sofa: pre's last rows
    pre = load_gaussians(bench / "pre.ply")
    truth = target_from_indices(pre.n, target).target
    with pytest.warns(R360Warning, match=f"dropped {N_NAN} of"):
        shifted = load_gaussians(with_bad_rows(bench / "pre.ply", tmp_path / "pre.ply", np.zeros(N_NAN, int)))
    assert shifted.n == pre.n and shifted.n_file == pre.n + N_NAN
    lifted = target_from_indices(shifted.n_file, target + N_NAN, rows=shifted.file_rows)
    assert np.array_equal(lifted.target, truth)
    # the same through the bundle: [target].indices of a pre file with 600 NaN rows first, as check runs it
    from r360gpu.lift.resolve import check_target

    b = tmp_path / "b"
    shutil.copytree(bench, b)
    shutil.copy(tmp_path / "pre.ply", b / "pre.ply")
    np.save(b / "target.npy", target + N_NAN)
    (b / "scene.toml").write_text((b / "scene.toml").read_text() + '\n[target]\nindices = "target.npy"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", R360Warning)
        got = check_target(load_bundle(b))
    assert np.array_equal(got.target, truth)
    # a target row the loader dropped is said, and the rest is the target
    said = []
    part = target_from_indices(shifted.n_file, np.r_[0, target + N_NAN], rows=shifted.file_rows, warn=said.append)
    assert np.array_equal(part.target, truth) and len(said) == 1 and "1 of the" in said[0]


@pytest.mark.filterwarnings("ignore:.*ignoring vertex properties my_label")
def test_residual_ply_has_the_files_rows_and_properties(bench, tmp_path):
    src = bench / "methods" / "floaters.ply"
    n0 = len(read_ply(src).arrays["vertex"])
    where = np.array([0, 0, 5, n0 // 2, n0])  # bad rows first, inside and last
    bad = with_bad_rows(src, tmp_path / "m.ply", where, extra=lambda n: np.arange(n, dtype=np.int32) % 3)
    with pytest.warns(R360Warning, match="dropped 5 of"):
        g = load_gaussians(bad)
    r = np.linspace(0.0, 1.0, g.n)
    vert = read_ply(write_residual_ply(tmp_path / "res.ply", g, r, source=bad)).arrays["vertex"]
    assert len(vert) == n0 + len(where) == g.n_file
    assert "my_label" in vert.dtype.names and np.array_equal(vert["my_label"], np.arange(len(vert)) % 3)
    dropped = np.setdiff1d(np.arange(g.n_file), g.rows)
    assert len(dropped) == len(where) and np.isnan(vert["residual"][dropped]).all()
    np.testing.assert_array_equal(vert["residual"][g.rows], r.astype(np.float32))
    # without a copyable source (a .splat, objects) the Gaussians' own properties, rows kept all the same
    vert = read_ply(write_residual_ply(tmp_path / "own.ply", g, r)).arrays["vertex"]
    assert len(vert) == g.n_file and np.isnan(vert["x"][dropped]).all()
    np.testing.assert_allclose(vert["x"][g.rows], g.means[:, 0])


def test_residual_ply_reads_back_without_a_warning(bench, tmp_path):
    g = load_gaussians(bench / "methods" / "floaters.ply")
    path = write_residual_ply(tmp_path / "res.ply", g, np.full(g.n, 0.25), source=bench / "methods" / "floaters.ply")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = load_gaussians(path)
    np.testing.assert_array_equal(back.means, g.means)


def test_top_residual_indices_are_rows_of_the_methods_file(bench, tmp_path, ctx):
    """The same method scored from its file and from the file with 600 NaN rows first: the same
    residuals, ``top`` shifted by 600, the residual PLY 600 vertices longer (NaN there)."""
    from r360gpu.pipeline import EvaluateOptions, evaluate

    b = tmp_path / "b"
    shutil.copytree(bench, b)
    with_bad_rows(bench / "methods" / "floaters.ply", b / "methods" / "nan.ply", np.zeros(N_NAN, int))
    (b / "scene.toml").write_text((b / "scene.toml").read_text() + '\n[methods.nan]\nscene = "methods/nan.ply"\n')
    opts = EvaluateOptions(n_boot=20, n_perm=10, pictures=False, boundary=False, controls=False, residuals=True)
    res = evaluate(str(b), out=tmp_path / "out", options=opts, device=ctx, progress=False)
    entry = res["scenes"]["room"]["residuals"]
    assert entry["floaters"]["top"] and entry["nan"]["top"] == [i + N_NAN for i in entry["floaters"]["top"]]
    plain = read_ply(tmp_path / "out" / entry["floaters"]["file"]).arrays["vertex"]["residual"]
    shifted = read_ply(tmp_path / "out" / entry["nan"]["file"]).arrays["vertex"]["residual"]
    assert len(shifted) == len(plain) + N_NAN and np.isnan(shifted[:N_NAN]).all()
    np.testing.assert_array_equal(shifted[N_NAN:], plain)
