"""[target] in scene.toml and scene_from_objects: masks rendered for every view from a few views'
masks, from Gaussian indices or from a box, checked against the synthetic generator's own masks."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from r360gpu.bundle import load_bundle
from r360gpu.errors import InputError
from r360gpu.io import load_gaussians, load_mask
from r360gpu.lift.resolve import resolve_target
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.render.sources import SceneSource
from r360gpu.synthetic import generate_benchmark, make_scene

ARGS = dict(seed=0, n_views=10, width=240, height=180, detail=0.25)
LIFT_VIEWS = 4


@pytest.fixture(scope="module")
def bench(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("lift")
    folder = generate_benchmark(root, scenes=("room",), methods=("clean", "floaters"), ctx=ctx, **ARGS)[0]
    return folder, make_scene("room", n_views=ARGS["n_views"], width=240, height=180, detail=ARGS["detail"])


def _variant(folder, tmp_path, table: str, given=()):
    """A copy of the bundle whose scene.toml has no top-level masks and the [target] ``table``."""
    dst = tmp_path / "room"
    shutil.copytree(folder, dst)
    text = (dst / "scene.toml").read_text().replace('masks = "masks"\n', "")
    (dst / "given").mkdir()
    for v in given:
        shutil.copy(dst / "masks" / f"{v}.png", dst / "given" / f"{v}.png")
    (dst / "scene.toml").write_text(text + "\n[target]\n" + table + "\n")
    return dst


def _object_views(folder):
    views = sorted(p.stem for p in (folder / "masks").glob("*.png"))
    shown = [v for v in views if load_mask(folder / "masks" / f"{v}.png").any()]
    return [shown[i] for i in np.linspace(0, len(shown) - 1, LIFT_VIEWS).round().astype(int)]


def _ious(folder, bundle, masks, skip=()):
    out = []
    for v in bundle.views:
        if v in skip:
            continue
        truth = load_mask(folder / "masks" / f"{v}.png")
        union = (truth | masks[v]).sum()
        if union:
            out.append((truth & masks[v]).sum() / union)
    return np.array(out)


@pytest.mark.parametrize("kind", ["masks", "indices", "box"])
def test_target_kinds_give_masks_like_the_generators(bench, tmp_path, ctx, kind):
    folder, scene = bench
    given = _object_views(folder) if kind == "masks" else ()
    if kind == "masks":
        table = 'masks = "given"'
    elif kind == "indices":
        np.save(tmp_path / "target.npy", np.arange(scene.background.n, scene.pre.n))
        table = f'indices = "{tmp_path / "target.npy"}"'
    else:  # the target's bounding box, a little larger (as a user would draw it)
        t = np.asarray(scene.target.means)
        lo, hi = t.min(0) - 0.02, t.max(0) + 0.02
        table = f"box = {{ min = {lo.tolist()}, max = {hi.tolist()} }}"
    bundle = load_bundle(_variant(folder, tmp_path, table, given))
    assert len(bundle.views) == ARGS["n_views"] and sorted(bundle.masks) == sorted(given)
    pre = SceneSource(bundle.pre.path, ctx=ctx)
    resolved, record = resolve_target(bundle, pre, ctx=ctx)
    assert record["source"] == kind and record["given"] == sorted(given)
    assert sorted(record["rendered"] + record["given"]) == bundle.views
    ious = _ious(folder, bundle, resolved.masks, skip=given)
    print(f"{kind}: held-out IoU mean {ious.mean():.4f} worst {ious.min():.4f} over {len(ious)} views")
    assert ious.mean() >= 0.95 and ious.min() >= 0.90
    if kind == "masks":  # lifted-target precision / recall, weighted by what the views see
        from r360gpu.lift.resolve import lifted_target

        lifted, _ = lifted_target(bundle, pre.gaussians, ctx=ctx)
        truth = np.arange(scene.pre.n) >= scene.background.n
        w = lifted.w_in + lifted.w_out
        tp = (w * (lifted.target & truth)).sum()
        prec, rec = tp / (w * lifted.target).sum(), tp / (w * truth).sum()
        print(f"lifted from {LIFT_VIEWS} views: weighted precision {prec:.4f} recall {rec:.4f}")
        assert prec >= 0.98 and rec >= 0.98
    pre.renderer.release()


def test_scoring_records_given_and_rendered_views(bench, tmp_path, ctx):
    folder, _ = bench
    given = _object_views(folder)
    bundle = load_bundle(_variant(folder, tmp_path, 'masks = "given"', given))
    res = evaluate(bundle, options=EvaluateOptions(n_boot=200, n_perm=100), device=ctx, progress=False)
    rec = res["scenes"]["room"]["target"]
    assert rec["given"] == sorted(given) and len(rec["rendered"]) == ARGS["n_views"] - len(given)
    assert rec["lifted_from"] == sorted(given)
    assert set(res["scenes"]["room"]["methods"]) == {"clean", "floaters"}
    from r360gpu.io import load_gaussians
    from r360gpu.report.outputs import summary_lines

    assert rec["of"] == load_gaussians(bundle.pre.path).n and 0 < rec["gaussians"] < rec["of"]
    print("target record:", {k: rec[k] for k in ("source", "gaussians", "of")}, len(rec["given"]), len(rec["rendered"]))
    assert (f"room: [target] lifted onto {rec['gaussians']} of {rec['of']} Gaussians of pre (from the masks of views "
            f"{', '.join(sorted(given))}); masks rendered for {len(rec['rendered'])} of {ARGS['n_views']} views"
            in summary_lines(res))


def test_scene_from_objects_with_a_target(bench, ctx):
    import r360gpu

    folder, scene = bench
    b = load_bundle(folder)
    pre = load_gaussians(b.pre.path)
    idx = np.arange(scene.background.n, scene.pre.n)
    obj = r360gpu.scene_from_objects("room", "sofa", {}, pre, {"clean": load_gaussians(b.methods["clean"].path)},
                                     cameras=b.cameras, target={"indices": idx})
    assert obj.views == b.views and obj.masks == {}
    with pytest.raises(InputError, match="needs cameras"):
        r360gpu.scene_from_objects("room", "sofa", {}, pre, {"clean": pre}, target={"indices": idx})
    with pytest.raises(InputError, match="target must be"):
        r360gpu.scene_from_objects("room", "sofa", {}, pre, {"clean": pre}, cameras=b.cameras, target={"x": 1})


def test_bad_target_tables(bench, tmp_path):
    from r360gpu.bundle.model import BundleError

    folder, _ = bench
    for i, (table, match) in enumerate((('masks = ""', "non-empty"), ("colour = 1", "needs masks, indices or box"),
                                        ("box = { min = [0, 0], max = [1, 1, 1] }", "3 finite"),
                                        ('masks = "missing"', "does not exist"))):
        sub = tmp_path / str(i)
        sub.mkdir()
        with pytest.raises(BundleError, match=match):
            load_bundle(_variant(folder, sub, table))


def test_one_view_lift_is_warned_and_empty_masks_refused(bench, tmp_path, ctx):
    folder, _ = bench
    one = _object_views(folder)[:1]
    bundle = load_bundle(_variant(folder, tmp_path, 'masks = "given"', one))
    pre = SceneSource(bundle.pre.path, ctx=ctx)
    said = []
    resolved, record = resolve_target(bundle, pre, ctx=ctx, warn=said.append)
    assert record["given"] == one and len(said) == 1 and "1 view" in said[0]
    empty = {v: np.zeros((180, 240), bool) for v in one}
    from dataclasses import replace

    with pytest.raises(InputError, match="no given target mask shows the target"):
        resolve_target(replace(bundle, masks=empty), pre, ctx=ctx)
    pre.renderer.release()
