"""Outputs a user can reuse (pipeline.reusable): the lifted target (indices and a labelled PLY), the
rendered target masks, the orbit's cameras.json, each written under --out, listed in results.json and
read back here equal to what the run used."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from r360gpu.synthetic import make_scene

ORBIT = 6


@pytest.fixture(scope="module")
def run(tmp_path_factory, ctx):
    from r360gpu.bundle.objects import scene_from_objects
    from r360gpu.pipeline import EvaluateOptions, evaluate

    scene = make_scene("garden", n_views=4, width=64, height=48, detail=0.1)
    idx = np.arange(scene.background.n, scene.pre.n)
    b = scene_from_objects("g", "bench", {}, scene.pre, {"clean": scene.background},
                           cameras={c.name: c for c in scene.cameras}, target={"indices": idx})
    out = tmp_path_factory.mktemp("reusable")
    opts = EvaluateOptions(n_boot=20, n_perm=10, orbit=ORBIT, pictures=False, boundary=False, controls=False)
    res = evaluate(b, out=out, options=opts, device=ctx, progress=False, log=lambda *a: None)
    return scene, b, idx, out, res


def test_lifted_target_indices_and_labelled_ply(run):
    from r360gpu.io.inria_ply import TARGET, load_inria_ply
    from r360gpu.io.ply import read_ply

    scene, _, idx, out, res = run
    files = res["scenes"]["g"]["target"]["files"]
    assert np.array_equal(np.load(out / files["indices"]), idx)
    vert = read_ply(out / files["ply"]).arrays["vertex"]
    assert len(vert) == scene.pre.n and np.array_equal(np.flatnonzero(vert[TARGET]), idx)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # r360gpu reads its own label back without a warning
        g = load_inria_ply(out / files["ply"])
    assert g.n == scene.pre.n and np.allclose(g.means, scene.pre.means, atol=1e-6)


def test_rendered_target_masks_are_the_masks_scored(run, ctx):
    from r360gpu.io import load_mask
    from r360gpu.lift.masks import TargetMaskRenderer

    scene, b, idx, out, res = run
    files = res["scenes"]["g"]["target"]["files"]
    assert sorted(files["masks"]) == sorted(res["scenes"]["g"]["target"]["rendered"]) == sorted(b.views)
    target = np.zeros(scene.pre.n, bool)
    target[idx] = True
    r = TargetMaskRenderer(scene.pre, target, ctx=ctx)
    seen = 0
    try:
        for v, path in files["masks"].items():
            m = load_mask(out / path, shape=(b.cameras[v].height, b.cameras[v].width))
            assert np.array_equal(m, r.mask(b.cameras[v]))
            seen += int(m.any())
    finally:
        r.release()
    assert seen >= 2


def test_orbit_cameras_json_and_masks_load_back_to_the_kept_poses(run, ctx):
    from r360gpu.io import load_mask
    from r360gpu.io.cameras_json import load_cameras_json
    from r360gpu.pipeline.orbit import orbit_bundle

    scene, b, idx, out, res = run
    orbit = res["scenes"]["g"]["orbit"]
    assert orbit["kept"] >= 1
    cams = load_cameras_json(out / orbit["files"]["cameras"])
    assert [c.name for c in cams] == orbit["views"] == sorted(orbit["files"]["masks"])
    again, _ = orbit_bundle(b, ORBIT, ctx=ctx)
    for c in cams:
        want = again.cameras[c.name]
        assert np.allclose(c.R, want.R, atol=1e-12) and np.allclose(c.t, want.t, atol=1e-12)
        assert (c.fx, c.fy, c.cx, c.cy, c.width, c.height) == (want.fx, want.fy, want.cx, want.cy, want.width,
                                                               want.height)
        m = load_mask(out / orbit["files"]["masks"][c.name], shape=(c.height, c.width))
        assert np.array_equal(m, np.asarray(again.masks[c.name]) != 0)
    assert "target" not in orbit["files"]  # a [target]'s lift is the scene's, written once


def test_results_csv_has_the_orbit_and_pruned_rows_marked_by_kind(run):
    import copy

    from r360gpu.report.results_io import results_csv_rows

    _, b, _, out, res = run
    header, rows = results_csv_rows(res)
    assert header[:5] == ["scene", "method", "view", "kind", "empty_target"]
    orbit = res["scenes"]["g"]["orbit"]
    assert [r[2] for r in rows if r[3] == "orbit"] == orbit["views"]
    assert [r[2] for r in rows if r[3] == "capture"] == list(b.views)
    with open(out / "results.csv") as f:  # the file written is these rows
        assert f.read().splitlines()[1:] == [",".join(r) for r in rows]
    doc = copy.deepcopy(res)
    doc["scenes"]["g"]["pruned"] = {"clean+pruned": {"method": "clean",
                                                     "views": doc["scenes"]["g"]["methods"]["clean"]["views"]}}
    _, rows = results_csv_rows(doc)
    pruned = [r for r in rows if r[3] == "pruned"]
    assert [r[1] for r in pruned] == ["clean+pruned"] * len(b.views)
    assert [r[4:] for r in pruned] == [r[4:] for r in rows if r[3] == "capture"]
    del doc["scenes"]["g"]["pruned"], doc["scenes"]["g"]["orbit"]
    header, _ = results_csv_rows(doc)
    assert "kind" not in header  # a plain run's results.csv is as before


def test_orbit_verdicts_are_marked_as_the_captures_are(run):
    import copy

    from r360gpu.report.orbit_table import orbit_lines, orbit_table
    from r360gpu.report.tables import render_markdown

    doc = copy.deepcopy(run[4])
    s = doc["scenes"]["g"]
    s["validity"] = {"s_sem": "ok", "s_geo": "ok", "s_str": "ok"}
    s["orbit"]["validity"] = {"s_sem": "ok", "s_geo": "blind", "s_str": "weak"}
    t = orbit_table(doc)
    row = [c.text for c in t.rows[0]]
    n = 4  # s_sem, s_geo, s_str, RQS
    capture, around = row[2:2 + n], row[2 + n:]
    assert not any("†" in c for c in capture)
    assert [c.endswith("†") for c in around] == [False, True, True, False]
    text = render_markdown(t)
    assert "† g orbit: s_geo blind, s_str weak" in text and "g capture" not in text
    assert any("at the orbit s_geo blind, s_str weak" in line for line in orbit_lines(doc))


def test_indices_and_labels_are_rows_of_the_file_as_written(tmp_path):
    """A loader that dropped rows: the indices name the file's rows, the PLY has every row (a
    dropped one labelled 0), so either can be given back as ``[target] indices``."""
    from r360gpu.io import Gaussians
    from r360gpu.io.gaussians import random_gaussians
    from r360gpu.io.inria_ply import TARGET
    from r360gpu.io.ply import read_ply
    from r360gpu.lift.target import load_indices
    from r360gpu.pipeline.reusable import write_target

    g0 = random_gaussians(8, sh_degree=0, seed=1)
    rows = np.array([0, 2, 3, 5, 6, 7, 9, 11])  # a file of 12 rows, 4 dropped
    g = Gaussians(g0.means, g0.scales, g0.quats, g0.opacities, g0.sh, file_rows=rows, file_count=12)
    target = np.zeros(8, bool)
    target[[1, 4, 7]] = True
    files = write_target(tmp_path, "s", g, target, {})
    assert np.load(tmp_path / files["indices"]).tolist() == [2, 6, 11]
    vert = read_ply(tmp_path / files["ply"]).arrays["vertex"]
    assert len(vert) == 12 and np.flatnonzero(vert[TARGET]).tolist() == [2, 6, 11]
    for path in (files["indices"], files["ply"]):
        assert np.array_equal(load_indices(tmp_path / path, 12, rows=rows).target, target)
