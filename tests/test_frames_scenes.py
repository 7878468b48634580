"""Scoring your own output in the right frame (docs/your-scene.md): a gsplat-normalised scene, a
nerfstudio-layout folder and an INRIA output folder, built from the synthetic generator; and the
frame check's verdict on aligned and misaligned scenes."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from frame_class import APPLIED, moved_gaussians
from gsplat_oracle import normalize_world
from r360gpu.bundle import load_bundle
from r360gpu.cli import main
from r360gpu.errors import InputError
from r360gpu.io import load_cameras, load_gaussians, save_cameras_json, save_ply, save_transforms_json
from r360gpu.io.colmap_points import save_points3d
from r360gpu.io.frames import Frame
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.render.sources import open_source
from r360gpu.synthetic import make_scene, write_bundle

OPTS = dict(n_boot=200, n_perm=100, boundary=False, pictures=False, controls=False)
FAST = ["--no-pictures", "--no-boundary", "--no-controls", "--n-boot", "200", "--n-perm", "100", "--quiet"]
@pytest.fixture(scope="module")
def synthetic(tmp_path_factory, ctx):
    """A small synthetic room (COLMAP cameras) with its pre and 'clean' method at SH degree 0."""
    root = tmp_path_factory.mktemp("synthetic")
    scene = make_scene("room", seed=0, n_views=5, width=96, height=72, detail=0.1)
    folder = write_bundle(scene, root / "room", methods=["clean"], ctx=ctx)
    for name in ("pre.ply", "methods/clean.ply"):
        save_ply(folder / name, load_gaussians(folder / name).with_sh_degree(0))
    return folder


def _toml(folder: Path, pre: str, clean: str, *, cameras: str = "cameras", extra: str = "") -> Path:
    (folder / "scene.toml").write_text(f'name = "room"\nprompt = "sofa"\ncameras = "{cameras}"\nmasks = "masks"\n'
                                       f'{extra}\n[pre]\nscene = "{pre}"\n\n[methods.clean]\nscene = "{clean}"\n')
    return folder


def _copy(synthetic: Path, dest: Path) -> Path:
    shutil.copytree(synthetic / "masks", dest / "masks")
    return dest


def _axes(res):
    return res["scenes"]["room"]["methods"]["clean"]["axes"]


@pytest.fixture(scope="module")
def plain(synthetic, tmp_path_factory, ctx):
    """The synthetic scene scored as it is (its splats in its cameras' frame)."""
    folder = _copy(synthetic, tmp_path_factory.mktemp("plain"))
    shutil.copytree(synthetic / "cameras", folder / "cameras")
    shutil.copy(synthetic / "pre.ply", folder / "pre.ply")
    shutil.copy(synthetic / "methods" / "clean.ply", folder / "clean.ply")
    _toml(folder, "pre.ply", "clean.ply")
    return folder, evaluate(folder, options=EvaluateOptions(**OPTS), device=ctx, progress=False)


def _same_renders(a: Path, b: Path, ctx, depth_rtol=1e-3):
    """pre of bundles a and b renders the same images, and the same depth in the cameras' units."""
    ba, bb = load_bundle(a), load_bundle(b)
    sa, sb = open_source(ba.pre, ctx=ctx), open_source(bb.pre, ctx=ctx)
    for v in ba.views[:2]:
        ia, ib = sa.images(v, ba.cameras[v]), sb.images(v, bb.cameras[v])
        assert np.abs(ia.rgb - ib.rgb).mean() < 2e-3
        assert np.abs(ia.alpha - ib.alpha).mean() < 2e-3
        both = (ia.alpha > 0.5) & (ib.alpha > 0.5)
        np.testing.assert_allclose(ib.depth[both], ia.depth[both], rtol=depth_rtol, atol=1e-3)
    return sb


def test_gsplat_normalised_scene_is_scored_with_frame_gsplat(synthetic, plain, tmp_path, ctx, capsys):
    """gsplat's simple_trainer (normalize_world_space=True) trains in the normalised world and saves its
    PLY there; frame = "gsplat" recomputes that world from the COLMAP model and its points3D."""
    folder = _copy(synthetic, tmp_path / "gsplat")
    shutil.copytree(synthetic / "cameras", folder / "colmap" / "sparse" / "0")
    cams = load_cameras(folder / "colmap")
    pre = load_gaussians(synthetic / "pre.ply")
    pts = pre.means[np.random.default_rng(0).choice(pre.n, 3000, replace=False)]  # the "sparse points"
    save_points3d(folder / "colmap" / "sparse" / "0", pts)
    c2w = np.stack([c.camera_to_world for c in sorted(cams, key=lambda c: c.name)])
    _, _, transform = normalize_world(c2w, pts.astype(np.float32))  # gsplat's own steps (tests/gsplat_oracle.py)
    frame = Frame.from_matrix(transform, "gsplat (oracle)")
    assert abs(frame.scale - 1.0) > 0.05  # the normalisation rescales the world: depth units change
    (folder / "results" / "ply").mkdir(parents=True)
    save_ply(folder / "results" / "ply" / "point_cloud_29999.ply", moved_gaussians(pre, frame))
    save_ply(folder / "results" / "clean.ply", moved_gaussians(load_gaussians(synthetic / "methods/clean.ply"), frame))
    _toml(folder, "results/ply/point_cloud_29999.ply", "results/clean.ply", cameras="colmap", extra='frame = "gsplat"')
    b = load_bundle(folder)
    np.testing.assert_allclose(b.pre.frame.m, transform, atol=1e-9)
    _same_renders(plain[0], folder, ctx)
    assert main(["score", str(folder), "--out", str(tmp_path / "out"), *FAST]) == 0
    res = json.loads((tmp_path / "out" / "results.json").read_text())
    assert res["scenes"]["room"]["frame_check"]["pre"]["level"] == "ok"
    for k in ("s_sem", "s_geo", "s_str", "iou_pre"):
        assert _axes(res)[k] == pytest.approx(_axes(plain[1])[k], abs=0.02), k
    assert not [w for w in res["warnings"] if "world frames" in w["message"]]
    # the same PLYs with the cameras as they are: the cameras miss the splats, refused naming the fix
    _toml(folder, "results/ply/point_cloud_29999.ply", "results/clean.ply", cameras="colmap")
    with pytest.raises(InputError, match="different world frames") as refused:
        evaluate(folder, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert 'frame = "gsplat"' in str(refused.value) and "--frame gsplat" in str(refused.value)
    # the remedy from the command line: --frame gsplat, for check and score alike
    capsys.readouterr()
    assert main(["check", str(folder), "--frame", "gsplat"]) == 0
    assert main(["score", str(folder), "--out", str(tmp_path / "out-cli"), "--frame", "gsplat", *FAST]) == 0
    cli = json.loads((tmp_path / "out-cli" / "results.json").read_text())
    assert cli["scenes"]["room"]["frame_check"]["pre"]["level"] == "ok"
    assert cli["scenes"]["room"]["sources"]["pre"]["frame"]["matrix"] == [list(r) for r in b.pre.frame.matrix]
    assert not [w for w in cli["warnings"] if "world frames" in w["message"]]
    for k in ("s_sem", "s_geo", "s_str", "iou_pre"):
        assert _axes(cli)[k] == _axes(json.loads((tmp_path / "out" / "results.json").read_text()))[k], k


def test_cameras_that_see_nothing_are_refused(synthetic, tmp_path, ctx, capsys):
    """A dataparser_transforms.json that belongs to another export sends the cameras far off:
    pre renders nothing at any checked view -> exit 2, one line naming the cause."""
    folder = _copy(synthetic, tmp_path / "far")
    shutil.copytree(synthetic / "cameras", folder / "cameras")
    shutil.copy(synthetic / "pre.ply", folder / "pre.ply")
    shutil.copy(synthetic / "methods" / "clean.ply", folder / "clean.ply")
    (folder / "dataparser_transforms.json").write_text(json.dumps(
        {"transform": [[1, 0, 0, 500.0], [0, 1, 0, 0], [0, 0, 1, 0]], "scale": 1.0}))
    _toml(folder, "pre.ply", "clean.ply")
    assert main(["score", str(folder), "--out", str(tmp_path / "out"), *FAST]) == 2
    err = capsys.readouterr().err
    assert "renders nothing" in err and "dataparser_transforms.json" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out" / "results.json").exists()
    with pytest.raises(InputError, match="different world frames"):
        evaluate(folder, options=EvaluateOptions(**OPTS), device=ctx, progress=False)


def test_nerfstudio_layout_applies_dataparser_transforms_beside_the_export(synthetic, plain, tmp_path, ctx,
                                                                           capsys):
    """ns-process-data -> data/transforms.json (applied_transform), ns-train splatfacto ->
    dataparser_transforms.json, ns-export gaussian-splat -> exports/splat/splat.ply in the dataparser frame."""
    folder = _copy(synthetic, tmp_path / "ns")
    cams = load_cameras(synthetic / "cameras")
    applied = Frame.from_matrix(APPLIED, "applied_transform")
    save_transforms_json(folder / "data" / "transforms.json", [applied.camera(c) for c in cams])
    doc = json.loads((folder / "data" / "transforms.json").read_text())
    doc["applied_transform"] = APPLIED.tolist()
    (folder / "data" / "transforms.json").write_text(json.dumps(doc))
    orient = np.eye(4)  # auto_orient_and_center_poses: a rotation and a shift of the transforms.json world
    a = np.radians(30.0)
    orient[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    orient[:3, 3] = [0.3, -0.2, 0.5]
    scale = 0.4
    a4 = np.eye(4)
    a4[:3] = APPLIED
    to_ns = Frame.from_matrix(np.diag([scale] * 3 + [1.0]) @ orient @ a4, "nerfstudio")  # COLMAP world -> ns
    for name, src in (("splat", "pre.ply"), ("clean", "methods/clean.ply")):
        (folder / "exports" / name).mkdir(parents=True)
        save_ply(folder / "exports" / name / "splat.ply", moved_gaussians(load_gaussians(synthetic / src), to_ns))
        (folder / "exports" / name / "dataparser_transforms.json").write_text(
            json.dumps({"transform": (orient @ a4)[:3].tolist(), "scale": scale}))
    _toml(folder, "exports/splat/splat.ply", "exports/clean/splat.ply", cameras="data/transforms.json")
    b = load_bundle(folder)
    assert b.pre.frame is not None and b.methods["clean"].frame.scale == pytest.approx(scale)
    _same_renders(plain[0], folder, ctx)
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["score", str(folder), "--out", str(out), *FAST]) == 0
    assert "frame: room pre: cameras moved by nerfstudio" in capsys.readouterr().out
    res = json.loads((out / "results.json").read_text())
    assert res["scenes"]["room"]["frame_check"]["pre"]["level"] == "ok"
    assert res["scenes"]["room"]["sources"]["pre"]["frame"]["scale"] == pytest.approx(scale)
    for k in ("s_sem", "s_geo", "s_str"):
        assert _axes(res)[k] == pytest.approx(_axes(plain[1])[k], abs=0.02), k
    # "frame = cameras" switches the file off: the cameras (inside the room) see walls at the wrong
    # places, and mostly not the target: refused, one line naming the cause and the fix
    (folder / "scene.toml").write_text((folder / "scene.toml").read_text().replace(
        'masks = "masks"\n', 'masks = "masks"\nframe = "cameras"\n'))
    capsys.readouterr()
    assert main(["score", str(folder), "--out", str(tmp_path / "out2"), *FAST]) == 2
    err = capsys.readouterr().err
    assert "scene room: pre (" in err and "dataparser_transforms" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "out2" / "results.json").exists()


def test_inria_output_folder_scored_as_the_walkthrough_says(synthetic, tmp_path, ctx):
    """docs/your-scene.md, INRIA output folder: point_cloud/iteration_N/point_cloud.ply and cameras.json
    as train.py writes them, scene.toml naming the folders."""
    folder = _copy(synthetic, tmp_path / "inria")
    cams = load_cameras(synthetic / "cameras")
    for name, src in (("pre", "pre.ply"), ("clean", "methods/clean.ply")):
        run = folder / "output" / name
        (run / "point_cloud" / "iteration_7000").mkdir(parents=True)
        (run / "point_cloud" / "iteration_30000").mkdir(parents=True)
        shutil.copy(synthetic / src, run / "point_cloud" / "iteration_30000" / "point_cloud.ply")
        (run / "point_cloud" / "iteration_7000" / "point_cloud.ply").write_bytes(b"not read: older iteration")
        save_cameras_json(run / "cameras.json", cams)
        (run / "cfg_args").write_text("Namespace(sh_degree=3)")
    (folder / "scene.toml").write_text(
        'name = "room"\nprompt = "sofa"\ncameras = "output/pre/cameras.json"\nmasks = "masks"\n\n'
        '[pre]\nscene = "output/pre"\n\n[methods.clean]\nscene = "output/clean"\n')
    assert main(["check", str(folder)]) == 0
    out = tmp_path / "out"
    assert main(["score", str(folder), "--out", str(out), *FAST]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["scenes"]["room"]["frame_check"]["pre"]["level"] == "ok"
    assert res["scenes"]["room"]["sources"]["pre"]["path"].endswith("iteration_30000/point_cloud.ply")
    assert 0.0 <= _axes(res)["rqs"] <= 1.0


def test_frame_option_is_validated(synthetic, tmp_path, capsys):
    """--frame takes the keywords of scene.toml's frame key or an existing file; anything else is one
    line and exit 2, before any work; a bundle of renders only has no frame to set."""
    for cmd in (["check", str(synthetic)], ["score", str(synthetic), "--out", str(tmp_path / "o")]):
        with pytest.raises(SystemExit) as e:
            main([*cmd, "--frame", "gsplat-normalised"])
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert "'gsplat-normalised' is neither one of auto, cameras, gsplat, gsplat-noflip nor an existing file" in err
        assert "Traceback" not in err
    assert not (tmp_path / "o").exists()
    dp = tmp_path / "dataparser_transforms.json"
    dp.write_text(json.dumps({"transform": np.eye(4)[:3].tolist(), "scale": 1.0}))
    from r360gpu.cli.frame_option import frame_value

    assert frame_value(str(dp)) == str(dp.resolve()) and frame_value("cameras") == "cameras"
    assert main(["check", str(synthetic), "--frame", str(dp)]) == 0
    renders = Path(__file__).parent / "data" / "compat_public" / "office_chair"  # a public folder: renders only
    capsys.readouterr()
    assert main(["check", str(renders), "--frame", "gsplat"]) == 2
    assert "--frame gsplat applies to splat scenes" in capsys.readouterr().out
