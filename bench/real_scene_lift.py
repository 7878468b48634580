"""Target lifting on a real third-party 3DGS file: masks of a few views lifted, rendered at the others.

Usage:
    python bench/real_scene_lift.py SCENE.ply [--views 12] [--given 3] [--size 320x240] [--masks alone]

SCENE.ply is any splat file r360gpu reads, e.g. the PlayCanvas engine's
``examples/assets/splats/guitar.compressed.ply`` or ``biker.compressed.ply``.
The target is the ball of Gaussians that ``bench/real_scene_controls.py`` cuts
(~8% of the scene); the cameras are a ring around it, as a capture around an
object would be: looking at the ball's centre from ``--distance`` times its
radius, 25% above its plane, up along the scene's longest axis.

The masks compared with ours are made independently of lifting, the way a
capture before and after a physical removal would give them: a pixel is
target where rendering the scene with and without the target's Gaussians
differs by more than ``--delta`` (any RGB channel, or alpha).  No share
threshold, lifting or target-mask renderer is involved.

``--masks alone`` gives instead the masks a user gets by rendering the
target's Gaussians alone (alpha > 0.5): they cover the target's whole
silhouette, including where something in front of it hides it, so the
occluder is lifted too.  The occluder check that scoring runs
(:func:`r360gpu.lift.occluders.find_occluders`) is printed for either kind,
and the figures below are printed again with the Gaussians it flags dropped
(``after drop``).  So is the check against a reference that scoring runs when
the scene has one (:func:`r360gpu.lift.occluders.unchanged_masks`, the
reference being the scene without the ball): each given mask's share of
pixels the removal left unchanged, and the figures for the given masks
trimmed to the pixels it changed.

``--given`` of those masks (views spread around the ring) are lifted onto the
scene's Gaussians with :func:`r360gpu.lift.lift_target`; the lifted target's
masks are then rendered at the other views with
:func:`r360gpu.lift.target_masks` and compared with the difference masks
(IoU per view).  Printed beside them, as the ceiling: the same comparison
for the true target (the ball itself) rendered by ``target_masks``, so what
is lifting error and what is the difference between the two mask
definitions can be told apart.  Also printed: the lifted Gaussians'
precision and recall against the ball, over all Gaussians and over those
that carry compositing weight in the given views.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_scene_controls import cut_target, ring  # noqa: E402

from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io import load_gaussians  # noqa: E402
from r360gpu.lift import lift_target, target_masks  # noqa: E402
from r360gpu.lift.occluders import drop_occluders, find_occluders, unchanged_masks, unchanged_pixels  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402


def target_ring(means: np.ndarray, target: np.ndarray, n: int, distance: float, width: int, height: int) -> dict:
    """n cameras around the target's centre at ``distance`` times its radius (the module docstring)."""
    centre = np.median(means[target], axis=0)
    radius = distance * float(np.quantile(np.linalg.norm(means[target] - centre, axis=1), 0.9))
    return ring(means, centre, radius, n, width, height)


def renders(g, cams: dict, ctx) -> dict:
    """{view: render} of ``g`` at ``cams``."""
    r = Renderer(g, ctx=ctx)
    try:
        return {v: r.render(c) for v, c in cams.items()}
    finally:
        r.release()


def difference_masks(pre: dict, cut: dict, delta: float) -> dict:
    """{view: (H, W) bool}: where the scene with (``pre``) and without the target (``cut``) renders differently."""
    return {v: (np.abs(a.rgb - cut[v].rgb).max(axis=-1) > delta) | (np.abs(a.alpha - cut[v].alpha) > delta)
            for v, a in pre.items()}


def alone_masks(g, target: np.ndarray, cams: dict, ctx) -> dict:
    """{view: (H, W) bool}: where the target's Gaussians rendered alone cover alpha > 0.5."""
    r = Renderer(g.subset(target), ctx=ctx)
    try:
        return {v: r.render(c).alpha > 0.5 for v, c in cams.items()}
    finally:
        r.release()


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = int((a | b).sum())
    return 1.0 if union == 0 else int((a & b).sum()) / union


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--views", type=int, default=12, help="cameras on the ring (default 12)")
    ap.add_argument("--given", type=int, default=3, help="views whose masks are lifted (default 3)")
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--distance", type=float, default=4.0, help="ring radius in target radii (default 4)")
    ap.add_argument("--masks", choices=("difference", "alone"), default="difference",
                    help="given masks: scene with vs without the target (default), or the target rendered alone")
    ap.add_argument("--delta", type=float, default=8 / 255, help="difference threshold of the masks (default 8/255)")
    args = ap.parse_args(argv)
    if not 1 <= args.given < args.views:
        ap.error("--given must be at least 1 and fewer than --views")
    width, height = (int(x) for x in args.size.lower().split("x"))
    ctx = get_context()
    g = load_gaussians(args.scene)
    truth = cut_target(g.means)
    cams = target_ring(g.means, truth, args.views, args.distance, width, height)
    t0 = time.perf_counter()
    pre_r, cut_r = renders(g, cams, ctx), renders(g.subset(~truth), cams, ctx)  # the reference: the ball removed
    masks = {v: m for v, m in difference_masks(pre_r, cut_r, args.delta).items() if m.any()}
    names = sorted(masks)
    lifted_from = alone_masks(g, truth, cams, ctx) if args.masks == "alone" else masks
    given = [names[round(i * len(names) / args.given)] for i in range(args.given)]
    held = [v for v in names if v not in given]
    print(f"{Path(args.scene).name}: {g.n} Gaussians, target (ball) {int(truth.sum())}; {len(names)} of "
          f"{len(cams)} views see it (difference masks, delta {args.delta:.4f}, {width}x{height}); "
          f"given {', '.join(given)} ({args.masks} masks)")
    lifted = lift_target(g, [cams[v] for v in given], [lifted_from[v] for v in given], ctx=ctx, per_view=True)
    t_lift = time.perf_counter() - t0
    occ = find_occluders(g, [cams[v] for v in given], lifted)
    print(f"occluder check: {int(occ.gaussians.sum())} flagged ({int((occ.gaussians & truth).sum())} of them in the "
          f"ball), {100 * occ.share:.1f}% of the lifted weight, by view {occ.by_view}: "
          f"{'WARNS' if occ.doubtful else 'silent'}")
    ref = unchanged_masks({v: lifted_from[v] for v in given}, pre_r, cut_r)
    print("reference check (share of each given mask unchanged by the removal): "
          + ", ".join(f"{v} {s:.1%}" for v, s in ref.shares.items()) + f": {'WARNS' if ref.doubtful else 'silent'}")
    trimmed = [lifted_from[v] & ~unchanged_pixels(pre_r[v], cut_r[v]) for v in given]
    by_ref = lift_target(g, [cams[v] for v in given], trimmed, ctx=ctx)
    for label, lt in (("lifted", lifted), ("after drop", drop_occluders(lifted, occ)),
                      ("masks trimmed to the pixels the removal changed", by_ref)):
        report(g, lt, truth, masks, cams, held, label, ctx)
    print(f"{time.perf_counter() - t0:.1f} s ({t_lift:.1f} s to the lifted target)")
    return 0


def report(g, lifted, truth, masks, cams, held, label, ctx) -> None:
    """Precision / recall against the ball and held-out IoU of ``lifted``'s masks."""
    print(f"\n## {label}")
    sel = lifted.target
    weighted = (lifted.w_in + lifted.w_out) > 0
    for label, pool in (("all Gaussians", np.ones(g.n, bool)), ("weighted in the given views", weighted)):
        tp = int((sel & truth & pool).sum())
        prec = tp / max(1, int((sel & pool).sum()))
        rec = tp / max(1, int((truth & pool).sum()))
        print(f"lifted target vs the ball, {label}: {int((sel & pool).sum())} selected, "
              f"precision {prec:.3f}, recall {rec:.3f}")
    held_cams = [cams[v] for v in held]
    ours = dict(zip(held, target_masks(g, sel, held_cams, ctx=ctx)))
    ceiling = dict(zip(held, target_masks(g, truth, held_cams, ctx=ctx)))
    rows = [(v, float(masks[v].mean()), iou(ours[v], masks[v]), iou(ceiling[v], masks[v]), iou(ours[v], ceiling[v]))
            for v in held]
    print("\n| held-out view | target area | IoU lifted vs difference | IoU true vs difference | IoU lifted vs true |")
    print("|---|---|---|---|---|")
    for v, area, a, b, c in rows:
        print(f"| {v} | {area:.1%} | {a:.3f} | {b:.3f} | {c:.3f} |")
    cols = np.array([r[2:] for r in rows])
    print(f"\nheld-out views {len(rows)} (mean / worst IoU): lifted target's masks vs the difference masks "
          f"{cols[:, 0].mean():.3f} / {cols[:, 0].min():.3f}; the true target's (ceiling) {cols[:, 1].mean():.3f} / "
          f"{cols[:, 1].min():.3f}; lifted vs true target's masks {cols[:, 2].mean():.3f} / {cols[:, 2].min():.3f}")


if __name__ == "__main__":
    sys.exit(main())
