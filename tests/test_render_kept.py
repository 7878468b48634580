"""Kept renders (render.kept): a render made before scoring stands for a new one only when
everything the render depends on is the same, once; the demo's flow gives the numbers and
pictures of a run that renders everything itself."""
from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from r360gpu.gpu import get_context
from r360gpu.io import save_ply
from r360gpu.pipeline import EvaluateOptions, evaluate
from r360gpu.pipeline.evaluate import Plan, evaluate_plan
from r360gpu.render.kept import KeptRenders
from r360gpu.render.sources import SceneSource
from r360gpu.synthetic import generate_benchmark, make_scene


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    sc = make_scene("room", seed=0, n_views=3, width=64, height=48, detail=0.08)
    path = tmp_path_factory.mktemp("kept") / "reference.ply"
    save_ply(path, sc.background)
    return sc, path


def _same(a, b) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("rgb", "depth", "alpha"))


def test_a_kept_render_is_taken_once_and_only_for_what_made_it(small, ctx):
    sc, path = small
    cam = sc.cameras[1]
    src = SceneSource(str(path), ctx=ctx)
    images = src.images(cam.name, cam)
    kept = KeptRenders()
    assert kept.keep(src, cam, images) and len(kept) == 1
    assert not kept.keep(src, cam, images)  # one per key

    shifted = dataclasses.replace(cam, cx=cam.cx + 1e-9)
    assert kept.take(src, shifted) is None
    assert kept.take(src, sc.cameras[0]) is None
    others = [SceneSource(str(path), ctx=ctx, background=(1.0, 0.0, 0.0)),
              SceneSource(str(path), ctx=ctx, depth="median"),
              SceneSource(str(path), ctx=ctx, render={"antialiased": True}),
              SceneSource(str(path), ctx=get_context(device=ctx.device))]  # another context on the same device
    try:
        for other in others:
            assert kept.take(other, cam) is None
    finally:
        for other in others:
            other.release()
    assert len(kept) == 1 and kept.taken == 0

    hit = kept.take(src, cam)
    assert hit is images and _same(hit, src.images(cam.name, cam))
    assert kept.take(src, cam) is None and len(kept) == 0 and kept.taken == 1
    src.release()


def test_a_rewritten_file_or_a_scene_in_memory_is_rendered_afresh(small, tmp_path, ctx):
    sc, path = small
    cam = sc.cameras[0]
    copy = tmp_path / "reference.ply"
    copy.write_bytes(path.read_bytes())
    src = SceneSource(str(copy), ctx=ctx)
    kept = KeptRenders()
    assert kept.keep(src, cam, src.images(cam.name, cam))
    st = copy.stat()
    os.utime(copy, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # same bytes, touched: another file for all we know
    assert kept.take(src, cam) is None
    src.release()

    mem = SceneSource(sc.background, ctx=ctx)
    assert not kept.keep(mem, cam, mem.images(cam.name, cam))  # no file to tell it by
    mem.release()


def test_the_store_holds_at_most_its_budget(small, ctx):
    sc, path = small
    src = SceneSource(str(path), ctx=ctx)
    renders = [(c, src.images(c.name, c)) for c in sc.cameras]
    one = sum(a.nbytes for a in (renders[0][1].rgb, renders[0][1].depth, renders[0][1].alpha))
    kept = KeptRenders(budget=2 * one)
    assert [kept.keep(src, c, im) for c, im in renders] == [True, True, False]
    assert kept.take(src, renders[2][0]) is None
    assert kept.take(src, renders[0][0]) is renders[0][1]
    assert kept.keep(src, *renders[2])  # room again once one was taken
    src.release()


def test_scoring_with_the_generators_renders_equals_scoring_alone(tmp_path, ctx):
    n_views = 4
    kept = KeptRenders()
    kw = dict(seed=0, n_views=n_views, width=96, height=72, scenes=("room",), detail=0.2, ctx=ctx)
    folder = generate_benchmark(tmp_path / "bench", **kw, kept=kept)[0]
    assert len(kept) == n_views  # every reference view the masks were drawn from
    opts = EvaluateOptions(n_boot=50, n_perm=20)
    plan = Plan.open(out=tmp_path / "with", options=opts, device=ctx, progress=False, kept=kept)
    a = evaluate_plan(folder, plan)
    assert kept.taken == n_views and len(kept) == 0
    b = evaluate(folder, out=tmp_path / "without", options=opts, device=ctx, progress=False)
    for r in (a, b):
        r.pop("timing"), r.pop("created")
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    pics = sorted(p.relative_to(tmp_path / "with") for p in (tmp_path / "with" / "pictures").rglob("*.png"))
    assert len(pics) >= n_views
    assert all((tmp_path / "with" / p).read_bytes() == (tmp_path / "without" / p).read_bytes() for p in pics)

    # a bundle reused from the last run brings no renders, and the run renders them itself
    again = KeptRenders()
    generate_benchmark(tmp_path / "bench", **kw, reuse=True, kept=again)
    assert len(again) == 0
