"""Identity and reference controls of the built-in structural probe, per scene.

Usage:
    python bench/structural_controls.py [--demo DIR] [--real SCENE.ply ...] [--cache DIR]
                                        [--probe graph|slic|hier] [--views N] [--size WxH]

For each scene the probe runs on the pre-removal and the reference renderings
at the evaluation views, and s_str is computed exactly as the structural axis
does (:func:`r360gpu.metrics.structural.structural_view`, reference mode):

* identity control: the unedited scene scored as the method (I_post = I_pre);
  a probe that sees the target gives a LOW value (<= 0.2 is "ok");
* reference control: the reference scored as the method (I_post = I_ref);
  a deterministic probe gives 1 here unless renders differ (>= 0.8 is "ok").

Scenes:
* ``--demo DIR``: the demo's synthetic benchmark folder (``DIR/room``,
  ``DIR/garden``; ``r360gpu demo --out X`` writes it to ``X/benchmark``, and it
  is generated here when DIR does not exist), scored at its own views and masks;
* ``--real SCENE.ply``: a third-party splat file, with the target cut out and
  the orbit cameras of ``bench/real_scene_controls.py`` (the Gaussians near a
  point on the longest axis); masks: the target where it is visible
  (:func:`visible_target`).

Printed: one row per scene (identity s_str, reference s_str, the verdict of
r360gpu.aggregate.validity's thresholds, probe seconds per view) and, with
``--per-view``, each view's sim.  ``--cache DIR`` keeps the renderings (npz) so
that reruns time only the probe.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from r360gpu.aggregate.validity import scene_validity  # noqa: E402
from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io import load_gaussians  # noqa: E402
from r360gpu.io.masks import load_mask  # noqa: E402
from r360gpu.metrics.structural import structural_view  # noqa: E402
from r360gpu.probes.builtin_structural import BuiltinStructuralProbe, StructuralParams  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402
from real_scene_controls import cut_target, orbit  # noqa: E402


def _render_all(g, cams: dict, ctx, background) -> dict:
    r = Renderer(g, ctx=ctx, background=background)
    return {v: np.clip(r.render(c).rgb, 0.0, 1.0) for v, c in cams.items()}


def demo_scene(folder: Path, ctx) -> tuple[dict, dict, dict]:
    """(pre images, reference images, masks) of one demo bundle folder."""
    from r360gpu.bundle import load_bundle
    b = load_bundle(folder)
    bg = b.options.background
    pre = load_gaussians(b.pre.path)
    ref = load_gaussians(b.reference.path)
    masks = {v: load_mask(b.masks[v]) for v in b.views}
    return _render_all(pre, b.cameras, ctx, bg), _render_all(ref, b.cameras, ctx, bg), masks


def visible_target(g, target: np.ndarray, cams: dict, ctx) -> dict:
    """{view: bool mask} of the target where it is visible, views where it is.

    As in a capture's annotation, M^v is the object as seen before removal: the
    target's own rendering (alpha > 0.5) where its median depth is not behind
    the whole scene's median depth (2% tolerance); parts hidden behind the rest
    of the scene are left out, since removing them changes nothing in the view.
    """
    only, full = Renderer(g.subset(target), ctx=ctx), Renderer(g, ctx=ctx)
    masks = {}
    for v, c in cams.items():
        t, f = only.render(c), full.render(c)
        m = (t.alpha > 0.5) & (t.median_depth <= f.median_depth * 1.02)
        if m.any():
            masks[v] = m
    return masks


def real_scene(path: Path, ctx, n_views: int, width: int, height: int) -> tuple[dict, dict, dict]:
    g = load_gaussians(path)
    target = cut_target(g.means)
    cams = orbit(g.means, n_views, width, height)
    masks = visible_target(g, target, cams, ctx)
    cams = {v: cams[v] for v in masks}
    return _render_all(g, cams, ctx, (0, 0, 0)), _render_all(g.subset(~target), cams, ctx, (0, 0, 0)), masks


def cached(cache: Path | None, key: str, make):
    if cache is None:
        return make()
    f = cache / f"{key}.npz"
    if f.exists():
        z = np.load(f)
        views = [str(v) for v in z["views"]]
        return tuple({v: z[f"{part}_{i}"] for i, v in enumerate(views)} for part in ("pre", "ref", "mask"))
    pre, ref, masks = make()
    views = sorted(masks)
    cache.mkdir(parents=True, exist_ok=True)
    arrays = {"views": np.array(views)}
    for i, v in enumerate(views):
        arrays[f"pre_{i}"] = pre[v].astype(np.float16)
        arrays[f"ref_{i}"] = ref[v].astype(np.float16)
        arrays[f"mask_{i}"] = masks[v]
    np.savez_compressed(f, **arrays)
    return cached(cache, key, make)


def controls(probe, pre: dict, ref: dict, masks: dict, ctx, per_view: bool) -> tuple[float, float, float, list]:
    """(identity s_str, reference s_str, probe seconds per view, per-view rows); empty targets skipped."""
    ident, refc, rows, seconds = [], [], [], 0.0
    for v in sorted(masks):
        m = np.asarray(masks[v]) != 0
        if not m.any():
            continue
        t0 = time.perf_counter()
        a = probe.predict_image(np.asarray(pre[v], np.float32), v)
        b = probe.predict_image(np.asarray(ref[v], np.float32), v)
        seconds += time.perf_counter() - t0
        si = structural_view(a, b, m, mode="reference", ctx=ctx)
        sr = structural_view(b, b, m, mode="reference", ctx=ctx)
        ident.append(si.s_str)
        refc.append(sr.s_str)
        rows.append((v, si.s_str, si.n_a, si.n_b, len(a.masks), len(b.masks), float(m.mean())))
    n = max(1, len(ident))
    return float(np.mean(ident)), float(np.mean(refc)), seconds / (2 * n), rows


def verdict(identity: float, reference: float) -> str:
    """The structural verdict r360gpu.aggregate.validity gives these two controls."""
    scene = {"methods": {"m": {"axes": {"s_str": identity}}},
             "controls": {"identity": {"axes": {"s_str": identity}, "views": []},
                          "reference": {"axes": {"s_str": reference}}}}
    return scene_validity(scene)[0]["s_str"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--demo", default=None, help="the demo's benchmark folder (generated there if absent)")
    ap.add_argument("--real", nargs="*", default=[], help="third-party splat files")
    ap.add_argument("--cache", default=None, help="keep renderings here (npz)")
    ap.add_argument("--views", type=int, default=12, help="orbit views of a real scene")
    ap.add_argument("--size", default="320x240", help="rendering size of a real scene")
    ap.add_argument("--per-view", action="store_true")
    ap.add_argument("--param", action="append", default=[], help="probe parameter override NAME=VALUE")
    args = ap.parse_args(argv)
    width, height = (int(x) for x in args.size.lower().split("x"))
    overrides = {}
    for p in args.param:
        k, _, val = p.partition("=")
        overrides[k] = type(getattr(StructuralParams(), k))(val)
    probe = BuiltinStructuralProbe(StructuralParams(**overrides))
    cache = Path(args.cache) if args.cache else None
    ctx = get_context()
    scenes = []
    if args.demo:
        root = Path(args.demo)
        if not root.exists():
            from r360gpu.synthetic import generate_benchmark
            generate_benchmark(root, ctx=ctx)
        for name in ("room", "garden"):
            scenes.append((f"demo {name}", lambda f=root / name: demo_scene(f, ctx), f"demo_{name}"))
    for path in args.real:
        p = Path(path)
        scenes.append((p.name, lambda p=p: real_scene(p, ctx, args.views, width, height),
                       f"real_{p.stem}_{args.views}_{width}x{height}_visible"))
    print(f"probe {probe.name}: {probe.params()}")
    print(f"{'scene':<28}{'views':>6}{'identity':>10}{'reference':>11}  {'verdict':<8}{'s/image':>9}")
    for label, make, key in scenes:
        pre, ref, masks = cached(cache, key, make)
        ident, refc, sec, rows = controls(probe, pre, ref, masks, ctx, args.per_view)
        print(f"{label:<28}{len(rows):>6}{ident:>10.3f}{refc:>11.3f}  {verdict(ident, refc):<8}{sec:>9.3f}")
        if args.per_view:
            for v, s, na, nb, ka, kb, area in rows:
                print(f"    {v:<14} sim {s:.3f}  retained {na}/{ka} pre, {nb}/{kb} ref  target {area:.1%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
