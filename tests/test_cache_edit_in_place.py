"""Cache keys hold content for every cached kind of cell: a method file edited in place (same
Gaussian count, so its description is unchanged) misses the view cache of a [target] bundle, of an
orbit run and of the pruned what-ifs, and the rerun equals a fresh run."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from r360gpu.io.ply import read_ply, write_ply
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.synthetic import generate_benchmark, make_scene

ARGS = dict(seed=0, n_views=4, width=64, height=48, detail=0.25)
OPTS = dict(n_boot=20, n_perm=10, pictures=False, boundary=False, controls=False)


@pytest.fixture(scope="module")
def bench(tmp_path_factory, ctx):
    root = tmp_path_factory.mktemp("edit")
    return generate_benchmark(root, scenes=("room",), methods=("clean", "floaters"), ctx=ctx, **ARGS)[0]


def edit_in_place(path, other):
    """Rewrite ``path`` with the first rows of ``other``'s vertices: the same count, other values."""
    n = len(read_ply(path).arrays["vertex"])
    src = read_ply(other).arrays["vertex"]
    assert len(src) >= n
    write_ply(path, [("vertex", src[:n])])


def _methods(res, part):
    scene = res["scenes"]["room"]
    if part == "pruned":
        return {m: e.get("axes") for m, e in scene["pruned"].items()}
    entry = scene if part is None else scene[part]
    return {m: e["axes"] for m, e in entry["methods"].items()}


def _target_bundle(bench, dst):
    scene = make_scene("room", n_views=ARGS["n_views"], width=64, height=48, detail=ARGS["detail"])
    shutil.copytree(bench, dst)
    np.save(dst / "target.npy", np.arange(scene.background.n, scene.pre.n))
    text = (dst / "scene.toml").read_text().replace('masks = "masks"\n', "")
    (dst / "scene.toml").write_text(text + '\n[target]\nindices = "target.npy"\n')
    return dst


KINDS = {  # cached kind of cell -> (bundle maker, options, the part of the scene entry it fills)
    "[target] view cells": (_target_bundle, {}, None),
    "orbit cells": (lambda bench, dst: shutil.copytree(bench, dst), {"orbit": 4}, "orbit"),
    "pruned what-if cells": (_target_bundle, {"prune_residuals": 50, "residuals": True}, "pruned"),
}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_a_method_edited_in_place_is_scored_anew(bench, tmp_path, ctx, kind):
    make, extra, part = KINDS[kind]
    b = make(bench, tmp_path / "b")
    opts = EvaluateOptions(**OPTS, **extra)
    out = tmp_path / "out"
    first = evaluate(str(b), out=out, options=opts, device=ctx, progress=False)
    edit_in_place(b / "methods" / "clean.ply", b / "methods" / "floaters.ply")
    again = evaluate(str(b), out=out, options=opts, device=ctx, progress=False)
    fresh = evaluate(str(b), out=tmp_path / "fresh", options=opts, device=ctx, progress=False)
    assert _methods(again, part) == _methods(fresh, part)
    assert _methods(again, part) != _methods(first, part)  # the edit changes the numbers
