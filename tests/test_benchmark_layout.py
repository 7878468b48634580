"""Each method with its own pre-removal source; METHOD=FOLDER groups; a benchmark root ROOT/<method>/<scene>/."""
from __future__ import annotations

import json
from collections import Counter
from dataclasses import replace

import pytest

from r360gpu.bundle import group_scene, load_benchmark, load_bundle, parse_method_folders
from r360gpu.cli import main
from r360gpu.errors import InputError
from r360gpu.pipeline import EvaluateOptions, evaluate

from public_benchmark import make_public_benchmark

OPTS = dict(n_boot=200, n_perm=100, boundary=False, pictures=False)
STAT = ["--n-boot", "200", "--n-perm", "100", "--no-boundary", "--no-pictures", "--quiet"]


@pytest.fixture(scope="module")
def root(tmp_path_factory, ctx):
    # AF has no garden folder: a method missing from a scene
    return make_public_benchmark(tmp_path_factory.mktemp("pub"), n_views=3, width=96, height=72, detail=0.25,
                                 skip=("AF/garden",), ctx=ctx)


def _axes(res, scene):
    return {m: e["axes"] for m, e in res["scenes"][scene]["methods"].items()}


def test_each_method_is_scored_against_its_own_pre(root, ctx, monkeypatch):
    from r360gpu.render.sources import RendersSource

    calls = Counter()
    images = RendersSource.images

    def counting(self, view, camera=None):
        calls[(str(self.spec.path), view)] += 1
        return images(self, view, camera)

    monkeypatch.setattr(RendersSource, "images", counting)
    b = group_scene({"GC": root / "GC" / "room", "AF": root / "AF" / "room", "OC": root / "OC" / "room"})
    assert b.name == "room" and list(b.methods) == ["GC", "AF", "OC"]
    assert {m: s.rgb_dir for m, s in b.method_pres.items()} == {m: root / m / "room" / "rgb" / "before"
                                                               for m in ("GC", "AF", "OC")}
    res = evaluate(b, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    # every source once per view: the default pre (GC's before) is shared with GC, not rendered twice
    assert set(calls.values()) == {1} and len(calls) == 6 * len(b.views)
    assert set(res["scenes"]["room"]["sources"]["method_pres"]) == {"AF", "OC"}
    grouped = _axes(res, "room")
    # the same geometric and structural axes as scoring each method's folder alone (its own before as pre)
    for m in ("GC", "AF", "OC"):
        alone = evaluate(load_bundle(root / m / "room", method_name=m), options=EvaluateOptions(**OPTS),
                         device=ctx, progress=False)
        a = _axes(alone, "room")[m]
        assert (grouped[m]["s_geo"], grouped[m]["s_str"]) == (a["s_geo"], a["s_str"]), m
    # with one shared pre instead (GC's), AF's IoU_pre is read on GC's pre renders: another value
    shared = evaluate(replace(b, method_pres={}), options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert _axes(shared, "room")["AF"]["iou_pre"] != grouped["AF"]["iou_pre"]
    assert (_axes(shared, "room")["GC"]["s_geo"], _axes(shared, "room")["GC"]["s_str"]) == \
        (grouped["GC"]["s_geo"], grouped["GC"]["s_str"])
    # two methods with the same own pre: one source, rendered once per view
    calls.clear()
    same = replace(b, method_pres={"AF": b.method_pres["AF"], "OC": b.method_pres["AF"]})
    res = evaluate(same, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert set(calls.values()) == {1} and len(calls) == 5 * len(b.views)
    # (the probe is fitted on the pre sources there are, here two: the semantic readings differ)
    assert (_axes(res, "room")["AF"]["s_geo"], _axes(res, "room")["AF"]["s_str"]) == \
        (grouped["AF"]["s_geo"], grouped["AF"]["s_str"])


def test_scene_toml_method_pre_table(root, tmp_path):
    (tmp_path / "scene.toml").write_text(f"""
prompt = "sofa"
masks = "{root}/GC/room/masks"
[pre]
rgb = "{root}/GC/room/rgb/before"
depth = "{root}/GC/room/depth/before"
[methods.GC]
rgb = "{root}/GC/room/rgb/after"
depth = "{root}/GC/room/depth/after"
[methods.AF]
rgb = "{root}/AF/room/rgb/after"
depth = "{root}/AF/room/depth/after"
[methods.AF.pre]
rgb = "{root}/AF/room/rgb/before"
depth = "{root}/AF/room/depth/before"
""")
    b = load_bundle(tmp_path)
    assert set(b.method_pres) == {"AF"} and b.pre_of("AF").rgb_dir == root / "AF" / "room" / "rgb" / "before"
    assert b.pre_of("GC") is b.pre and "pre/AF" in b.sources()
    fp = b.fingerprint()
    text = (tmp_path / "scene.toml").read_text()
    (tmp_path / "scene.toml").write_text(text.replace('rgb = "' + str(root) + '/AF/room/rgb/before"',
                                                      'rgb = "' + str(root) + '/OC/room/rgb/before"'))
    assert load_bundle(tmp_path).fingerprint() != fp
    (tmp_path / "scene.toml").write_text(text.replace(f'{root}/AF/room/depth/before', "nope")
                                         + '[methods.GC.pre]\nrenders = "x"\nsurprise = 1\n')
    with pytest.raises(InputError) as e:
        load_bundle(tmp_path)
    msg = str(e.value)
    assert "depth folder of [methods.AF.pre] does not exist" in msg
    assert "unknown key 'surprise' in [methods.GC.pre]" in msg


def test_method_folder_arguments():
    plain, pairs = parse_method_folders(["GC=runs/gc/room", "scenes/room", "a/b=c", "AF=x"])
    assert pairs == [("GC", "runs/gc/room"), ("AF", "x")] and plain == ["scenes/room", "a/b=c"]


def test_members_must_agree(root, tmp_path):
    import shutil

    odd = tmp_path / "room"
    shutil.copytree(root / "AF" / "room", odd)
    (odd / "masks" / "view_000.png").unlink()
    with pytest.raises(InputError, match="different views"):
        group_scene({"GC": root / "GC" / "room", "AF": odd})
    shutil.copytree(root / "AF" / "room", tmp_path / "r2" / "room")
    (tmp_path / "r2" / "room" / "prompt.txt").write_text("lamp\n")
    with pytest.raises(InputError, match="different prompts"):
        group_scene({"GC": root / "GC" / "room", "AF": tmp_path / "r2" / "room"})
    assert group_scene({"GC": root / "GC" / "room", "AF": tmp_path / "r2" / "room"}, prompt="sofa").prompt == "sofa"


def test_cli_method_groups_views_flag_and_names(root, tmp_path, capsys):
    out = tmp_path / "o"
    # --views before the folders: the flag takes one value, so the folders stay folders
    rc = main(["score", "--views", "view_000", "--views", "view_001,view_002", f"GC={root}/GC/room",
               f"AF={root}/AF/room", "--out", str(out), *STAT])
    assert rc == 0, capsys.readouterr().err
    doc = json.loads((out / "results.json").read_text())
    assert list(doc["scenes"]) == ["room"] and list(doc["scenes"]["room"]["methods"]) == ["GC", "AF"]
    assert doc["scenes"]["room"]["views"] == ["view_000", "view_001", "view_002"]
    # --scene-name, and --method-name / --prompt for a plain public-layout folder
    rc = main(["score", f"GC={root}/GC/room", "--scene-name", "bedroom_table", "--out", str(tmp_path / "o2"),
               "--views", "view_000", *STAT])
    assert rc == 0 and "bedroom_table" in json.loads((tmp_path / "o2" / "results.json").read_text())["scenes"]
    rc = main(["score", str(root / "OC" / "room"), "--method-name", "OC", "--prompt", "couch",
               "--views", "view_000", "--out", str(tmp_path / "o3"), *STAT])
    doc = json.loads((tmp_path / "o3" / "results.json").read_text())
    assert rc == 0 and list(doc["scenes"]["room"]["methods"]) == ["OC"] and doc["scenes"]["room"]["prompt"] == "couch"
    capsys.readouterr()
    assert main(["score", "--out", str(tmp_path / "o4"), *STAT]) == 2
    assert "nothing to score" in capsys.readouterr().err


def test_benchmark_root_reports_a_missing_method_and_uses_the_common_set(root, tmp_path, capsys):
    bundles, notes = load_benchmark(root)
    assert [b.name for b in bundles] == ["garden", "room"]
    assert list(bundles[0].methods) == ["GC", "OC"] and list(bundles[1].methods) == ["AF", "GC", "OC"]
    assert len(notes) == 1 and "garden" in notes[0] and "AF" in notes[0]
    out = tmp_path / "o"
    assert main(["score", "--benchmark", str(root), "--out", str(out), *STAT]) == 0
    printed = capsys.readouterr().out
    assert "no folder for method AF" in printed
    doc = json.loads((out / "results.json").read_text())
    assert doc["aggregate"]["methods"] == ["GC", "OC"]
    assert any("left out: AF (missing from garden)" in n for n in doc["notes"])
    tables = (out / "tables.md").read_text()
    assert "Note: cross-scene tables use the methods every scene has (GC, OC); left out: AF" in tables
    assert "left out: AF" in (out / "report.html").read_text()
    iou_rows = tables[tables.index("mIoU_pre -> mIoU_post"):].splitlines()
    garden = next(r for r in iou_rows if r.startswith("| garden"))
    assert garden.count("→") == 2 and "--" in garden  # AF did not run on garden: shown as missing
    assert "mIoU_pre of a method with its own pre-removal renders is measured on them" in tables
    # scenes x methods in one run: each method's own IoU_pre per scene
    iou_pre = {m: doc["scenes"]["room"]["methods"][m]["axes"]["iou_pre"] for m in ("GC", "AF", "OC")}
    assert len(set(iou_pre.values())) == 3


def test_members_cameras_must_agree():
    import numpy as np

    from r360gpu.bundle.group import _same_cameras
    from r360gpu.io.camera import Camera

    def cam(tx):
        return Camera(R=np.eye(3), t=np.array([tx, 0.0, 0.0]), fx=50.0, fy=50.0, cx=24.0, cy=16.0, width=48,
                      height=32, name="v0")

    _same_cameras({"v0": cam(1.0)}, {"v0": cam(1.0 + 1e-9)}, "b", "room")
    with pytest.raises(InputError, match="camera of view 'v0' in b differs"):
        _same_cameras({"v0": cam(1.0)}, {"v0": cam(1.1)}, "b", "room")


def test_the_appearance_probe_is_fitted_on_every_pre_source(root, ctx, monkeypatch):
    """A probe fitted on one pipeline's pre renders alone can miss the object in another's
    (IoU_pre 0 for that method): with own pres the fit sees the fit views of every pre source."""
    from r360gpu.probes.builtin_semantic import BuiltinAppearanceProbe

    seen = []
    fit = BuiltinAppearanceProbe.fit

    def recording(self, images, masks):
        seen.append(len(images))
        return fit(self, images, masks)

    monkeypatch.setattr(BuiltinAppearanceProbe, "fit", recording)
    b = group_scene({"GC": root / "GC" / "room", "AF": root / "AF" / "room", "OC": root / "OC" / "room"})
    n_fit = min(EvaluateOptions().fit_views, len(b.views))
    evaluate(b, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert seen == [3 * n_fit]  # GC's (the default), AF's and OC's pre renders
    seen.clear()
    evaluate(replace(b, method_pres={}), options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert seen == [n_fit]
