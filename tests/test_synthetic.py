"""Built-in synthetic benchmark: determinism, files that load back, masks, method edits,
and the key property: the geometric axis orders the simulated methods as a person would."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io import load_cameras, load_gaussians, load_mask
from r360gpu.metrics.geometric import acc_depth_view
from r360gpu.render import NEAR_PLANE, Renderer
from r360gpu.synthetic import (
    DEFAULT_METHODS, METHODS, generate_benchmark, make_method, make_scene, target_masks, view_kinds, write_bundle,
)
from r360gpu.synthetic.methods import FLOATER_FRACTION, RETRAIN_POSITION_SIGMA
from r360gpu.synthetic.primitives import Solid, sh_to_rgb

# GHT with the reference prior (nu=1000, tau=300) needs enough pixels per view to
# separate a spread-out depth change from "no change"; 320x240 is comfortably above
# the size where it collapses to one class (160x120 does on some views).
GEO_SIZE = (320, 240)
DETAIL = 0.25
N_VIEWS = 8


@pytest.fixture(scope="module")
def scenes():
    return {name: make_scene(name, seed=0, n_views=N_VIEWS, width=GEO_SIZE[0], height=GEO_SIZE[1], detail=DETAIL)
            for name in ("room", "garden")}


@pytest.fixture(scope="module")
def masks(scenes, ctx):
    return {name: target_masks(sc, ctx=ctx) for name, sc in scenes.items()}


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------------------- files


def test_same_seed_gives_byte_identical_files(tmp_path, ctx):
    kwargs = dict(seed=3, n_views=4, width=96, height=72, detail=0.08, ctx=ctx)
    a = generate_benchmark(tmp_path / "a", **kwargs)
    b = generate_benchmark(tmp_path / "b", **kwargs)
    assert [p.name for p in a] == [p.name for p in b] == ["room", "garden"]
    fa, fb = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert fa.keys() == fb.keys() and len(fa) > 20
    assert all(fa[k] == fb[k] for k in fa), [k for k in fa if fa[k] != fb[k]]
    c = generate_benchmark(tmp_path / "c", **{**kwargs, "seed": 4}, scenes=("room",))
    assert (c[0] / "pre.ply").read_bytes() != fa["room/pre.ply"]


def test_a_generation_stopped_half_way_is_regenerated_by_the_next_run(tmp_path, ctx, monkeypatch):
    """Ctrl-C after a bundle's first files: the next run rewrites the folder (it is marked as a
    synthetic bundle before anything is written) instead of refusing it as a foreign folder."""
    import r360gpu.synthetic.bundle as sb

    kwargs = dict(seed=2, n_views=3, width=64, height=48, detail=0.08, scenes=("room",), ctx=ctx)
    clean = generate_benchmark(tmp_path / "clean", **kwargs)[0]

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(sb, "save_ply", interrupted)  # the cameras are written, the first .ply is not
        with pytest.raises(KeyboardInterrupt):
            generate_benchmark(tmp_path / "stopped", **kwargs, reuse=True)
    assert (tmp_path / "stopped" / "room" / "cameras").is_dir()
    assert not (tmp_path / "stopped" / "room" / "scene.toml").exists()
    reused = []
    again = generate_benchmark(tmp_path / "stopped", **kwargs, reuse=True, reused=reused)[0]
    assert reused == [] and _files(again) == _files(clean)


def test_an_unchanged_benchmark_is_reused_and_a_changed_one_rewritten(tmp_path, ctx):
    import os

    kwargs = dict(seed=3, n_views=3, width=64, height=48, detail=0.05, scenes=("room",), ctx=ctx)
    first = _files(generate_benchmark(tmp_path, **kwargs)[0])
    ply = tmp_path / "room" / "pre.ply"
    stamp = ply.stat().st_mtime_ns
    reused: list = []
    generate_benchmark(tmp_path, **kwargs, reuse=True, reused=reused)
    assert reused == ["room"] and ply.stat().st_mtime_ns == stamp
    # other bytes of the same size with the old mtime restored (as `cp -p` leaves them): rewritten
    data = bytearray(ply.read_bytes())
    data[-1] ^= 0xFF
    ply.write_bytes(bytes(data))
    os.utime(ply, ns=(stamp, stamp))
    reused = []
    generate_benchmark(tmp_path, **kwargs, reuse=True, reused=reused)
    assert reused == [] and _files(tmp_path / "room") == first
    generate_benchmark(tmp_path, **{**kwargs, "n_views": 2}, reuse=True, reused=reused)
    assert reused == [] and not (tmp_path / "room" / "masks" / "view_002.png").exists()


def test_bundle_files_load_back(tmp_path, scenes, masks, ctx):
    tomllib = pytest.importorskip("tomllib")
    sc = scenes["room"]
    folder = write_bundle(sc, tmp_path / "room", seed=0, ctx=ctx)
    cfg = tomllib.loads((folder / "scene.toml").read_text(encoding="utf-8"))
    assert cfg["name"] == "room" and cfg["prompt"] == "sofa"
    assert list(cfg["methods"]) == list(DEFAULT_METHODS)

    pre = load_gaussians(folder / cfg["pre"]["scene"])
    np.testing.assert_array_equal(pre.means, sc.pre.means)
    np.testing.assert_allclose(pre.scales, sc.pre.scales, rtol=1e-6)
    np.testing.assert_allclose(pre.sh, sc.pre.sh, atol=1e-6)
    ref = load_gaussians(folder / cfg["reference"]["scene"])
    np.testing.assert_array_equal(ref.means, sc.background.means)
    for m, entry in cfg["methods"].items():
        g = load_gaussians(folder / entry["scene"])
        assert g.n == make_method(sc, m, seed=0).n

    cams = load_cameras(folder / cfg["cameras"])
    assert [c.name for c in cams] == [c.name for c in sc.cameras]
    for a, b in zip(cams, sc.cameras):
        np.testing.assert_allclose(a.R, b.R, atol=1e-12)
        np.testing.assert_allclose(a.t, b.t, atol=1e-12)
        assert (a.fx, a.cx, a.width, a.height) == (b.fx, b.cx, b.width, b.height)
    for cam in cams:
        loaded = load_mask(folder / cfg["masks"] / f"{cam.name}.png", (cam.height, cam.width))
        np.testing.assert_array_equal(loaded, masks["room"][cam.name])

    meta = json.loads((folder / "synthetic.json").read_text())
    assert meta["view_kinds"] == sc.view_kinds and meta["gaussians"]["target"] == sc.target.n


def test_transforms_cameras_and_regeneration_removes_stale_files(tmp_path, ctx):
    sc = make_scene("garden", n_views=5, width=64, height=48, detail=0.08)
    folder = write_bundle(sc, tmp_path / "g", methods=["clean", "hole"], ctx=ctx)
    assert len(list((folder / "masks").glob("*.png"))) == 5
    small = make_scene("garden", n_views=3, width=64, height=48, detail=0.08)
    write_bundle(small, folder, methods=["clean"], camera_format="transforms", ctx=ctx)
    assert sorted(p.stem for p in (folder / "masks").glob("*.png")) == ["view_000", "view_001", "view_002"]
    assert sorted(p.name for p in (folder / "methods").iterdir()) == ["clean.ply"]
    assert not (folder / "cameras").exists()
    cams = load_cameras(folder / "transforms.json")
    assert [c.name for c in cams] == ["view_000", "view_001", "view_002"]
    assert 'cameras = "transforms.json"' in (folder / "scene.toml").read_text()


def test_bad_arguments_and_foreign_folders_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="unknown"):
        generate_benchmark(tmp_path, scenes=("kitchen",))
    with pytest.raises(InputError, match="n_views"):
        make_scene("room", n_views=0)
    with pytest.raises(InputError, match="camera_format"):
        generate_benchmark(tmp_path, camera_format="nerf")
    with pytest.raises(InputError, match="unknown synthetic method"):
        make_method(make_scene("room", n_views=1, width=32, height=24, detail=0.05), "blur")
    foreign = tmp_path / "room"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="refusing"):
        generate_benchmark(tmp_path, n_views=2, width=32, height=24, detail=0.05, scenes=("room",))
    assert (foreign / "notes.txt").read_text() == "mine"


# ---------------------------------------------------------------------------- cameras and masks


def test_view_kinds():
    assert view_kinds(1) == ["object"]
    k20 = view_kinds(20)
    assert k20.count("away") == 2 and k20.count("edge") == 2 and k20[-2:] == ["away", "away"]
    assert view_kinds(8).count("away") == 1 and view_kinds(8).count("edge") == 1


def test_masks_cover_the_visible_target_only(scenes, masks, ctx):
    for name, sc in scenes.items():
        target = Renderer(sc.target, ctx=ctx)
        occluded = 0
        for cam in sc.cameras:
            m = masks[name][cam.name]
            kind = sc.view_kinds[cam.name]
            silhouette = target.render(cam).alpha > 0.5
            assert not (m & ~silhouette).any()  # never outside the target
            occluded += int((silhouette & ~m).sum())
            if kind == "away":
                assert not m.any(), (name, cam.name)
            elif kind == "edge":
                assert m.any() and (m[:, 0].any() or m[:, -1].any()), (name, cam.name)
        target.release()
        aimed = [c.name for c in sc.cameras if sc.view_kinds[c.name] != "away"]
        assert sum(masks[name][v].any() for v in aimed) >= 0.8 * len(aimed)
        # Occluders (plant, tree, table) hide part of the target in some views.
        assert occluded > 0.02 * sum(int(masks[name][v].sum()) for v in aimed)


def test_hidden_background_is_behind_the_rendered_target(scenes, ctx):
    for sc in scenes.values():
        hidden = sc.hidden
        assert 0 < hidden.sum() < 0.1 * sc.background.n
        pts = np.asarray(sc.background.means[hidden], np.float64)
        target = Renderer(sc.target, ctx=ctx)
        framed_total = behind_total = 0
        for cam in sc.cameras:
            uv, z = cam.project(pts)
            with np.errstate(invalid="ignore"):
                framed = ((z > NEAR_PLANE) & (uv[:, 0] >= 0) & (uv[:, 0] < cam.width)
                          & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height))
            if not framed.any():
                continue
            r = target.render(cam)
            col, row = uv[framed, 0].astype(int), uv[framed, 1].astype(int)
            behind = (r.alpha[row, col] > 0.5) & (r.depth[row, col] < z[framed])
            framed_total += int(framed.sum())
            behind_total += int(behind.sum())
        target.release()
        # Wherever a camera frames a hidden Gaussian, the rendered target is in front of it
        # (up to Gaussians at the silhouette's soft edge).
        assert framed_total > 0 and behind_total >= 0.95 * framed_total
        # Floor / ground right under the middle of the target is hidden.
        base = sc.solids[0]
        under = np.all(np.abs(sc.background.means[:, :2] - np.asarray(base.center[:2])) < 0.1, axis=1)
        under &= np.abs(sc.background.means[:, 2]) < 0.03
        assert under.any() and hidden[under].all()


def test_solid_blocks_lines_of_sight():
    box = Solid((0.0, 0.0, 0.5), (1.0, 1.0, 1.0), yaw=0.3)
    eye = np.array([0.0, -5.0, 2.0])
    pts = np.array([[0.0, 0.0, 0.0],    # on the floor under the box
                    [0.0, 8.0, 0.0],    # far behind it, seen over the top
                    [0.0, 1.2, 0.0],    # just behind it, hidden
                    [3.0, 0.0, 0.0],    # beside it
                    [0.0, -2.0, 0.0]])  # in front of it
    np.testing.assert_array_equal(box.blocks(eye, pts), [True, False, True, False, False])
    np.testing.assert_array_equal(box.contains(pts + [0, 0, 0.5]), [True, False, False, False, False])


# ---------------------------------------------------------------------------- methods


def test_methods_edit_the_scene_as_intended(scenes):
    sc = scenes["room"]
    nb, nt = sc.background.n, sc.target.n
    out = {m: make_method(sc, m, seed=0) for m in METHODS}

    clean = out["clean"]
    assert clean.n == nb
    assert np.abs(clean.means - sc.background.means).max() < 10 * RETRAIN_POSITION_SIGMA

    rec = out["recoloured"]
    assert rec.n == nb + nt
    np.testing.assert_array_equal(rec.means[nb:], sc.target.means)
    np.testing.assert_array_equal(rec.scales[nb:], sc.target.scales)
    np.testing.assert_array_equal(rec.opacities[nb:], sc.target.opacities)
    old, new = sh_to_rgb(sc.target.sh), sh_to_rgb(rec.sh[nb:])
    assert np.abs(new - old).mean() > 0.1  # the sofa's colours are gone

    hole = out["hole"]
    assert sc.hidden.sum() > 0 and hole.n == nb - int(sc.hidden.sum())
    # Every kept Gaussian is a jittered visible background Gaussian, in order.
    kept = np.asarray(sc.background.means[~sc.hidden])
    assert np.abs(hole.means - kept).max() < 10 * RETRAIN_POSITION_SIGMA

    over = out["over_removal"]
    removed = sc.in_neighbourhood()
    assert over.n == nb - int(removed.sum())
    assert not (removed & sc.shell).any()
    removed_parts = {sc.part_names[i] for i in np.unique(sc.part_index[removed])}
    assert {"lamp", "rug", "side-table"} <= removed_parts

    flo = out["floaters"]
    assert flo.n == nb + round(FLOATER_FRACTION * nt)
    residue = np.asarray(flo.means[nb:])
    lo, hi = np.min(sc.target.means, axis=0), np.max(sc.target.means, axis=0)
    assert np.all(residue > lo - 0.2) and np.all(residue < hi + 0.2)
    assert np.median(flo.scales[nb:]) < np.median(sc.target.scales)


def test_geometric_axis_orders_methods_as_expected(scenes, masks, ctx):
    """recoloured keeps the geometry (acc_depth ~ 0), clean / hole / over_removal remove it,
    floaters leave part of it; views without target are excluded."""
    for name, sc in scenes.items():
        pre = Renderer(sc.pre, ctx=ctx)
        d_pre = {c.name: pre.render(c).depth for c in sc.cameras}
        pre.release()
        acc = {}
        for method in METHODS:
            r = Renderer(make_method(sc, method, seed=0), ctx=ctx)
            views = [acc_depth_view(d_pre[c.name], r.render(c).depth, masks[name][c.name], ctx=ctx)
                     for c in sc.cameras]
            r.release()
            for c, v in zip(sc.cameras, views):
                assert v.excluded == (sc.view_kinds[c.name] == "away"), (name, method, c.name)
            acc[method] = float(np.mean([v.acc_depth for v in views if not v.excluded]))
        msg = f"{name}: {acc}"
        assert acc["recoloured"] < 0.05, msg
        for method in ("clean", "hole", "over_removal"):
            assert acc[method] > acc["recoloured"] + 0.3, msg
        assert acc["recoloured"] + 0.08 < acc["floaters"] < acc["clean"] - 0.2, msg
