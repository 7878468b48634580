"""End to end: a small synthetic benchmark scored by evaluate() and by the CLI."""
from __future__ import annotations

import json

import pytest

from r360gpu.cli import main
from r360gpu.errors import R360Warning
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.report.outputs import write_outputs
from r360gpu.synthetic import generate_benchmark

OPTS = dict(n_boot=500, n_perm=200)


@pytest.fixture(scope="module")
def bundle(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("bench")
    return generate_benchmark(root, seed=0, n_views=5, width=240, height=180, scenes=("room",), detail=0.5, ctx=ctx)[0]


@pytest.fixture(scope="module")
def scored(bundle, tmp_path_factory, ctx):
    out = tmp_path_factory.mktemp("out")
    res = evaluate(bundle, out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    return out, res


def _axes(res):
    return {m: e["axes"] for m, e in res["scenes"]["room"]["methods"].items()}


def test_scores_rank_the_failure_modes(scored):
    _, res = scored
    ax = _axes(res)
    assert set(ax) == {"clean", "floaters", "recoloured", "hole", "over_removal"}
    # recoloured keeps the geometry: the geometric axis must see it.
    assert ax["clean"]["s_geo"] > ax["recoloured"]["s_geo"] + 0.3
    assert ax["clean"]["rqs"] > ax["recoloured"]["rqs"]
    assert ax["floaters"]["s_geo"] < ax["clean"]["s_geo"]
    for a in ax.values():
        for k in ("s_sem", "s_geo", "s_str", "rqs"):
            assert 0.0 <= a[k] <= 1.0
        assert a["n_views"] >= 1 and a["psnr"] is not None and a["lpips"] is None
    assert res["adapter"]["name"] and res["adapter"]["backend"]
    assert res["aggregate"]["overall"]["clean"]["rqs"] == pytest.approx(ax["clean"]["rqs"])
    assert set(res["sensitivity"]["boundary"]["clean"]["acc_depth"]) >= {"E15", "Original", "D15"}


def test_outputs_are_written(scored):
    out, res = scored
    paths = write_outputs(res, out)
    for p in paths.values():
        assert p.is_file() and p.stat().st_size > 0
    doc = json.loads(paths["json"].read_text())
    assert doc["schema"] == "r360gpu.results/1"
    assert doc["scenes"]["room"]["methods"]["clean"]["plot"] == "plots/room/clean.png"
    assert (out / doc["scenes"]["room"]["methods"]["hole"]["pictures"]["view_001"]).is_file()


def test_plots_drawn_while_scoring_are_those_of_the_finished_results(scored, tmp_path):
    """evaluate() draws a scene's plots as soon as the scene is scored; write_outputs draws the
    same from the finished document, and writes plots handed to it as they are."""
    from r360gpu.report.outputs import method_plots, scene_records

    out, res = scored
    entry = res["scenes"]["room"]
    drawn = method_plots("room", scene_records(entry))
    assert set(drawn) == set(entry["methods"])
    for m in entry["methods"]:
        assert (out / "plots" / "room" / f"{m}.png").read_bytes() == drawn[m]
    given = {"room": {m: f"plot of {m}".encode() for m in entry["methods"]}}
    with pytest.warns(R360Warning, match="not embedded"):  # (no pictures in this folder)
        write_outputs(json.loads(json.dumps(res)), tmp_path, plots=given)
    assert (tmp_path / "plots" / "room" / "hole.png").read_bytes() == b"plot of hole"
    with pytest.warns(R360Warning, match="not embedded"):
        write_outputs(json.loads(json.dumps(res)), tmp_path, plots={"room": {"hole": b"one only"}})
    assert (tmp_path / "plots" / "room" / "hole.png").read_bytes() == drawn["hole"]  # incomplete: drawn here


def test_rerun_resumes_from_the_cache_and_force_recomputes(bundle, scored, ctx):
    out, first = scored
    again = evaluate(bundle, out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert "render" not in again["timing"]["stages_s"]  # nothing rendered: every view came from the cache
    assert _axes(again) == _axes(first)
    # a run killed half-way: the missing views are recomputed, the rest reused
    views = sorted((out / ".r360cache" / "views").glob("*/room/clean/*.json"))
    views[-1].unlink()
    partial = evaluate(bundle, out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False)
    assert partial["timing"]["stages_s"].get("render", 0) > 0
    assert _axes(partial) == _axes(first)
    forced = evaluate(bundle, out=out, options=EvaluateOptions(**OPTS), device=ctx, progress=False, force=True)
    assert _axes(forced) == _axes(first)  # deterministic


def test_library_call_on_a_callers_device_without_output(bundle, ctx):
    res = evaluate(bundle, device=ctx.device, options=EvaluateOptions(views=("view_00[12]",), boundary=False, **OPTS),
                   progress=False)
    assert res["scenes"]["room"]["views"] == ["view_001", "view_002"]


def test_cli_score_and_bad_input(bundle, tmp_path, capsys):
    rc = main(["score", str(bundle), "--out", str(tmp_path / "o"), "--views", "view_001", "--no-boundary",
               "--n-boot", "100", "--n-perm", "50", "--quiet"])
    out = capsys.readouterr().out
    assert rc == 0 and "report:" in out and (tmp_path / "o" / "report.html").is_file()
    assert main(["score", str(tmp_path / "nope"), "--out", str(tmp_path / "o2"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "nope" in err and "Traceback" not in err and len(err.strip().splitlines()) >= 1
    assert main(["score", str(bundle), "--out", str(tmp_path / "o3"), "--semantic-probe", "builtin-graphseg"]) == 2
    assert "structural probe" in capsys.readouterr().err
    assert main(["score", str(bundle), "--out", str(tmp_path / "o3"), "--xi", "1.5"]) == 2


def test_scene_from_objects_with_renders_already_on_the_device(bundle, ctx):
    """Library use from another GPU pipeline: pre/post renders handed over as
    device buffers; the geometric axis reads depth on the device."""
    import r360gpu
    from r360gpu.bundle import load_bundle
    from r360gpu.io import load_gaussians, load_mask
    from r360gpu.render import Renderer
    from r360gpu.render.sources import DeviceViewsSource

    b = load_bundle(bundle)
    views = b.views[:2]
    masks = {v: load_mask(b.masks[v]) for v in views}
    pre_g = load_gaussians(b.pre.path)
    post_g = load_gaussians(b.methods["recoloured"].path)
    dev = {name: DeviceViewsSource({v: Renderer(g, ctx=ctx).render_device(b.cameras[v]) for v in views}, ctx=ctx)
           for name, g in (("pre", pre_g), ("post", post_g))}
    scene = r360gpu.scene_from_objects("room", "sofa", masks, dev["pre"], {"recoloured": dev["post"]})
    res = r360gpu.evaluate(scene, device=ctx, options=r360gpu.EvaluateOptions(**OPTS), progress=False)
    # the same numbers as rendering the same scenes from memory
    ref = r360gpu.evaluate(
        r360gpu.scene_from_objects("room", "sofa", masks, pre_g, {"recoloured": post_g}, cameras=b.cameras),
        device=ctx, options=r360gpu.EvaluateOptions(**OPTS), progress=False)
    a, r = _axes(res)["recoloured"], _axes(ref)["recoloured"]
    assert a["s_geo"] == r["s_geo"] and a["s_sem"] == r["s_sem"] and a["s_str"] == r["s_str"]
    assert res["scenes"]["room"]["sources"]["pre"]["kind"] == "device"


def test_pictures_are_outputs_the_view_cache_knows(bundle, tmp_path, ctx):
    """A run without pictures, then one with: the pictures appear; a deleted one is written again."""
    opts = dict(views=("view_00[12]",), boundary=False, **OPTS)
    out = tmp_path / "o"
    first = evaluate(bundle, out=out, options=EvaluateOptions(pictures=False, **opts), device=ctx, progress=False)
    assert not (out / "pictures").exists()
    assert all(not e["pictures"] for e in first["scenes"]["room"]["methods"].values())
    second = evaluate(bundle, out=out, options=EvaluateOptions(**opts), device=ctx, progress=False)
    pics = second["scenes"]["room"]["methods"]["clean"]["pictures"]
    assert set(pics) == {"view_001", "view_002"} and all((out / p).is_file() for p in pics.values())
    assert _axes(second) == _axes(first)
    gone = out / pics["view_002"]
    gone.unlink()
    third = evaluate(bundle, out=out, options=EvaluateOptions(**opts), device=ctx, progress=False)
    assert gone.is_file() and _axes(third) == _axes(first)
    # everything there: nothing is rendered again
    fourth = evaluate(bundle, out=out, options=EvaluateOptions(**opts), device=ctx, progress=False)
    assert "render" not in fourth["timing"]["stages_s"]


def test_every_source_is_rendered_once_per_view(bundle, ctx, monkeypatch):
    """The appearance probe's fit renders of pre are the renders the views are scored with."""
    from collections import Counter

    from r360gpu.render.sources import SceneSource

    calls = Counter()
    images = SceneSource.images

    def counting(self, view, camera):
        calls[(str(self.path), view)] += 1
        return images(self, view, camera)

    monkeypatch.setattr(SceneSource, "images", counting)
    res = evaluate(bundle, options=EvaluateOptions(boundary=False, **OPTS), device=ctx, progress=False)
    n_sources = 2 + len(res["scenes"]["room"]["methods"])  # pre, reference, methods
    assert len(calls) == n_sources * len(res["scenes"]["room"]["views"])
    assert set(calls.values()) == {1}


def test_scenes_from_objects_rescored_when_what_they_hold_changes(bundle, tmp_path, ctx):
    """The per-view cache of a scene built from objects is keyed by what is scored, not by its
    description: Gaussians of the same count with other values, moved cameras and a changed
    target each give fresh results; renders held on the device are never cached (their content
    is not known without reading them back)."""
    import numpy as np

    import r360gpu
    from r360gpu.bundle import load_bundle
    from r360gpu.io import Camera, build_gaussians, load_gaussians, load_mask
    from r360gpu.render import Renderer
    from r360gpu.render.sources import DeviceViewsSource

    b = load_bundle(bundle)
    views = b.views[:2]
    masks = {v: load_mask(b.masks[v]) for v in views}
    pre_g = load_gaussians(b.pre.path)
    post = load_gaussians(b.methods["floaters"].path)
    brighter = build_gaussians(post.means, post.scales, post.quats, post.opacities, post.sh + 0.5, source="edit")
    opts = r360gpu.EvaluateOptions(pictures=False, boundary=False, **OPTS)
    out = tmp_path / "o"

    def run(method, cameras=b.cameras, masks=masks, at=out):
        scene = r360gpu.scene_from_objects("room", "sofa", masks, pre_g, {"m": method}, cameras=cameras)
        return r360gpu.evaluate(scene, out=at, device=ctx, options=opts, progress=False)["scenes"]["room"]["methods"]["m"]

    def fresh(method, **kw):
        return run(method, at=None, **kw)

    first = run(post)
    assert first["views"] == fresh(post)["views"]
    edited = run(brighter)  # same count, other colours: scored again
    assert edited["views"] == fresh(brighter)["views"] and edited["views"] != first["views"]
    moved = {v: Camera(c.R, c.t, c.fx * 1.1, c.fy * 1.1, c.cx, c.cy, c.width, c.height, c.name)
             for v, c in b.cameras.items()}
    assert run(post, cameras=moved)["views"] == fresh(post, cameras=moved)["views"] != first["views"]
    shifted = {v: np.roll(m, 7, axis=1) for v, m in masks.items()}
    assert run(post, masks=shifted)["views"] == fresh(post, masks=shifted)["views"] != first["views"]
    assert run(post)["views"] == first["views"]  # unchanged: the cache still serves it

    dev_out = tmp_path / "dev"
    for g in (post, brighter):
        dev = DeviceViewsSource({v: Renderer(g, ctx=ctx).render_device(b.cameras[v]) for v in views}, ctx=ctx)
        pre_dev = DeviceViewsSource({v: Renderer(pre_g, ctx=ctx).render_device(b.cameras[v]) for v in views}, ctx=ctx)
        scene = r360gpu.scene_from_objects("room", "sofa", masks, pre_dev, {"m": dev})
        got = r360gpu.evaluate(scene, out=dev_out, device=ctx, options=opts, progress=False)
        assert got["scenes"]["room"]["methods"]["m"]["views"] == fresh(g)["views"]
    assert not list(dev_out.rglob("views"))  # nothing cached for device renders
