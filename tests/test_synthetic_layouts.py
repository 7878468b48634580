"""r360gpu.synthetic.layouts: a bundle written as an INRIA output folder, a gsplat output, a nerfstudio export
and public Remove360 folders scores as the bundle does (docs/your-scene.md runs its walkthroughs on them)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.bundle import load_bundle
from r360gpu.errors import InputError
from r360gpu.io.frames import gsplat_frame
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.synthetic import make_scene, write_bundle
from r360gpu.synthetic.layouts import LAYOUTS, MARKER, write_layouts

OPTS = dict(n_boot=100, n_perm=50, boundary=False, pictures=False, controls=False)
AXES = ("s_sem", "s_geo", "s_str", "rqs", "iou_pre", "iou_post")


@pytest.fixture(scope="module")
def written(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("layouts")
    scene = make_scene("room", seed=0, n_views=3, width=64, height=48, detail=0.1)
    bundle = write_bundle(scene, root / "bundle" / "room", methods=["clean", "floaters"], ctx=ctx)
    return bundle, write_layouts(bundle, root / "layouts", ctx=ctx)


def _axes(folder, ctx):
    res = evaluate(folder, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    (scene,) = res["scenes"].values()
    return {m: v["axes"] for m, v in scene["methods"].items()}, res


def test_every_layout_scores_as_the_bundle(written, ctx):
    bundle, layouts = written
    assert sorted(layouts) == sorted(LAYOUTS)
    plain, _ = _axes(bundle, ctx)
    for layout in ("inria", "gsplat", "nerfstudio"):
        (folder,) = layouts[layout]
        got, res = _axes(folder, ctx)
        assert list(got) == list(plain), layout
        for m in plain:
            for k in AXES:
                assert got[m][k] == pytest.approx(plain[m][k], abs=1e-6), (layout, m, k)
        assert res["scenes"]["room"]["frame_check"]["pre"]["level"] == "ok", layout
        assert not [w for w in res["warnings"] if "world frames" in w["message"]], layout
    for folder in layouts["public"]:
        method = folder.parent.name
        assert folder.name == "room_sofa" and load_bundle(folder).layout == "remove360"
        got, _ = _axes(folder, ctx)
        assert list(got) == ["after"]
        for k in AXES:  # the colours rounded to 16 bits: equal to well below a pixel's weight
            assert got["after"][k] == pytest.approx(plain[method][k], abs=1e-4), (method, k)


def test_moved_layouts_are_in_the_trainers_frames(written):
    """gsplat's PLYs in gsplat's normalised world, nerfstudio's in their dataparser frame: not the bundle's."""
    bundle, layouts = written
    gs = layouts["gsplat"][0]
    frame = gsplat_frame(gs / "colmap")
    assert abs(frame.scale - 1.0) > 0.05
    b = load_bundle(gs)
    assert b.pre.frame is not None and np.allclose(b.pre.frame.m, frame.m)
    ns = load_bundle(layouts["nerfstudio"][0])
    doc = json.loads((layouts["nerfstudio"][0] / "exports" / "pre" / "dataparser_transforms.json").read_text())
    assert ns.pre.frame.scale == pytest.approx(doc["scale"]) and abs(doc["scale"] - 1.0) > 0.05
    assert load_bundle(layouts["inria"][0]).pre.path.name == "point_cloud.ply"


def test_a_foreign_folder_is_not_replaced(written, tmp_path, ctx):
    bundle, _ = written
    (tmp_path / "inria" / "room").mkdir(parents=True)
    (tmp_path / "inria" / "room" / "mine.txt").write_text("keep")
    with pytest.raises(InputError, match=MARKER):
        write_layouts(bundle, tmp_path, layouts=["inria"], ctx=ctx)
    assert (tmp_path / "inria" / "room" / "mine.txt").read_text() == "keep"
    with pytest.raises(InputError, match="unknown"):
        write_layouts(bundle, tmp_path, layouts=["colmap"], ctx=ctx)
    # an earlier folder of ours is replaced
    write_layouts(bundle, tmp_path / "again", layouts=["inria"], ctx=ctx)
    write_layouts(bundle, tmp_path / "again", layouts=["inria"], ctx=ctx)
    assert (tmp_path / "again" / "inria" / "room" / MARKER).is_file()
    assert not list((tmp_path / "again" / "inria").glob(".*"))


def test_convert_command(written, tmp_path, capsys):
    from r360gpu.cli import main

    bundle, layouts = written
    assert main(["convert", str(bundle), "--out", str(tmp_path), "--layouts", "inria,public"]) == 0
    out = capsys.readouterr().out
    assert f"-> {tmp_path / 'inria' / 'room'} (inria)" in out and out.count("(public)") == 2
    assert load_bundle(tmp_path / "inria" / "room").pre.path.name == "point_cloud.ply"
    assert not (tmp_path / "gsplat").exists()
    # a bundle whose splats are in another frame (gsplat's) is refused, nothing written
    assert main(["convert", str(layouts["gsplat"][0]), "--out", str(tmp_path / "again")]) == 2
    err = capsys.readouterr().err
    assert "not a splat file in the cameras' frame" in err and "Traceback" not in err
    assert not (tmp_path / "again").exists()
    assert main(["convert", str(bundle), "--out", str(tmp_path), "--layouts", "colmap"]) == 2
    assert "unknown or no layouts" in capsys.readouterr().err
