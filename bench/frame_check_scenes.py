"""The frame check's confusion table: its verdicts on correctly framed scenes and on wrong frames.

Usage:
    python bench/frame_check_scenes.py [--size WxH] [--views N] [--detail D] [--wrong N] [--seed S]
                                       [--frame-seed S] [--real SCENE.ply ...] [--real-size WxH] [--json PATH]

Scenes: the demo's room and garden (r360gpu.synthetic, at --size with --views cameras) and any
real splat file given with --real (e.g. the PlayCanvas engine's examples/assets/splats/biker
and guitar .compressed.ply), framed as bench/real_scene_controls.py frames one: cameras on a
ring around the scene, a target cut out and its masks rendered.  Per scene the frame check
(r360gpu.metrics.frame_check.check_views, with the scene's reference: pre without the target, in
pre's frame) is run on

* the correct frame: the scene as it is; for the demo scenes also the splats moved into gsplat's
  normalised world (normalize_world_space recomputed from the cameras and the splat centres)
  with that frame declared (what ``frame = "gsplat"`` does);
* --wrong random wrong frames: a random similarity (a rotation uniform over all rotations, a
  scale log-uniform in [0.1, 10] about the world origin, the object or the cameras' centroid, a
  shift of up to 1.5 orbit radii) applied to the cameras and not declared, drawn from a generator
  seeded with 2026 + --frame-seed (default --seed), scene after scene.  A draw is *wrong*
  when the target's own silhouette, seen by the moved cameras, overlaps its masks by a median IoU
  under 0.5 over the checked views (the masks no longer mark the object); a draw that leaves the
  object under its masks is listed apart (the scores would still measure its removal);
* for the demo scenes also gsplat's normalised world with the cameras as they are (not declared).

Printed: one row per case with --detail-rows, and the confusion table (truth x verdict).  These are
the tables of docs/your-scene.md ("The check") and docs/input-validation.md;
tests/test_frame_check_class.py checks a small draw of the same class.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the frame generators shared with the tests (tests/frame_class.py)

from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io import load_gaussians  # noqa: E402
from r360gpu.io.frames import Frame, gsplat_normalization  # noqa: E402
from r360gpu.metrics import frame_check  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402
from r360gpu.render.sources import SceneSource  # noqa: E402
from r360gpu.synthetic import make_scene  # noqa: E402
from r360gpu.synthetic.masks import target_masks  # noqa: E402

from common import header  # noqa: E402
from frame_class import moved_gaussians, random_similarity  # noqa: E402
from real_scene_controls import cut_target, orbit  # noqa: E402

#: Median silhouette IoU under this: the masks no longer mark the object (a wrong frame).
IOU_WRONG = 0.5
#: The wrong frames' scales: log-uniform in this range.
SCALES = (0.1, 10.0)
#: A real scene's target pixel is visible when its depth is below this times the rest's.
REAL_DEPTH_SLACK = 1.01
#: Mask errors (pixels too wide, too narrow) under which the correct frame is also checked.
MISDRAWN = (2, -2, 1, -1)
VERDICTS = ("ok", "note", "refuse")


class Case:
    """One scene to check: pre (Gaussians), its target's Gaussians, the reference (pre without
    the target), cameras and masks."""

    def __init__(self, name, pre, target, reference, cams, masks):
        self.name, self.pre, self.target, self.cams, self.masks = name, pre, target, cams, masks
        self.reference = reference
        self.pick = frame_check.checked_views([v for v in cams if masks[v].any()])
        centre = target.means.mean(axis=0)
        self.centres = [np.zeros(3), centre, np.mean([c.center for c in cams.values()], axis=0)]
        self.radius = float(np.median([np.linalg.norm(c.center - centre) for c in cams.values()]))

    def verdict(self, gaussians, reference, frame, ctx) -> frame_check.FrameVerdict:
        """The check on ``gaussians`` as pre, with ``reference`` (Gaussians, in the same frame) as the
        reference, the cameras moved by ``frame``."""
        src, ref = SceneSource(gaussians, ctx=ctx, frame=frame), SceneSource(reference, ctx=ctx, frame=frame)
        try:
            views = []
            for v in self.pick:
                img = src.images(v, self.cams[v])
                views.append((v, self.cams[v], img.alpha, img.depth, self.masks[v], img.rgb))
            return frame_check.check_views(views, lambda v: ref.images(v, self.cams[v]))
        finally:
            src.release()
            ref.release()

    def object_iou(self, frame, ctx) -> float:
        """Median over the checked views of the IoU of the target's silhouette (cameras moved by
        ``frame``) and its mask."""
        src = SceneSource(self.target, ctx=ctx, frame=frame)
        try:
            ious = []
            for v in self.pick:
                sil = src.images(v, self.cams[v]).alpha > 0.5
                ious.append((sil & self.masks[v]).sum() / max(1, (sil | self.masks[v]).sum()))
            return float(np.median(ious))
        finally:
            src.release()


def demo_case(name, a, ctx) -> Case:
    w, h = (int(x) for x in a.size.split("x"))
    scene = make_scene(name, seed=a.seed, n_views=a.views, width=w, height=h, detail=a.detail)
    masks = target_masks(scene, ctx=ctx)
    return Case(name, scene.pre, scene.target, scene.background, {c.name: c for c in scene.cameras}, masks)


def real_case(path, a, ctx) -> Case:
    """A real splat file framed as bench/real_scene_controls.py frames it; the masks are the target's
    visible pixels (in front of the rest of the scene, as an annotator would draw them)."""
    w, h = (int(x) for x in a.real_size.split("x"))
    g = load_gaussians(path)
    target = cut_target(g.means)
    cams = orbit(g.means, a.views, w, h)
    masks = visible_masks(g, target, cams, ctx)
    return Case(Path(path).name.split(".")[0], g, g.subset(target), g.subset(~target),
                {v: cams[v] for v in masks}, masks)


def visible_masks(g, target: np.ndarray, cams: dict, ctx) -> dict:
    """{view: (H, W) bool} of the views that see the target: its visible pixels (the target's
    Gaussians rendered alone, where they are in front of the rest of the scene)."""
    only_target, rest = Renderer(g.subset(target), ctx=ctx), Renderer(g.subset(~target), ctx=ctx)
    try:
        masks = {}
        for v, c in cams.items():
            t, b = only_target.render(c), rest.render(c)
            masks[v] = (t.alpha > 0.5) & ((t.depth < REAL_DEPTH_SLACK * b.depth) | (b.alpha < 0.5))
        return {v: m for v, m in masks.items() if m.any()}
    finally:
        only_target.release()
        rest.release()


def misdrawn(masks: dict, px: int) -> dict:
    """The masks ``px`` pixels too wide (> 0) or too narrow (< 0): an annotator's error."""
    k = np.ones((2 * abs(px) + 1,) * 2, np.uint8)
    op = cv2.dilate if px > 0 else cv2.erode
    return {v: op(m.astype(np.uint8), k) > 0 for v, m in masks.items()}


def readings(v: frame_check.FrameVerdict) -> dict:
    steps = [x.step for x in v.views if x.step is not None]
    return {"level": v.level, "coverage": [x.coverage for x in v.views], "target": [x.target for x in v.views],
            "cones": v.cones, "step": float(np.median(steps)) if steps else None, "removed": v.removed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="160x120", help="the demo scenes' image size")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--detail", type=float, default=0.2)
    ap.add_argument("--wrong", type=int, default=50, help="random wrong frames per scene")
    ap.add_argument("--seed", type=int, default=0, help="the demo scenes' seed")
    ap.add_argument("--frame-seed", type=int, default=None,
                    help="the wrong frames' seed (default: --seed); their generator is seeded with 2026 + it")
    ap.add_argument("--real", nargs="*", default=[], help="real splat files, framed as real_scene_controls.py does")
    ap.add_argument("--real-size", default="320x240")
    ap.add_argument("--detail-rows", action="store_true", help="print one row per case")
    ap.add_argument("--json", default=None, help="write every case's readings here")
    a = ap.parse_args()
    frame_seed = a.seed if a.frame_seed is None else a.frame_seed
    header(f"frame check confusion table (demo {a.size}, {a.views} views, detail {a.detail}, real {a.real_size}, "
           f"{a.wrong} wrong frames per scene, seed {a.seed}, frame seed {frame_seed}; {time.strftime('%Y-%m-%d')})")
    ctx = get_context()
    rows = []

    def record(scene, truth, label, v, iou=None):
        rows.append({"scene": scene, "truth": truth, "label": label, "iou": iou, **readings(v)})
        if a.detail_rows:
            r = rows[-1]
            print(f"{scene:8s} {truth:22s} {label:34s} iou {'-' if iou is None else f'{iou:.2f}':>5s} "
                  f"cov {min(r['coverage']):.2f} tgt {min(t for t in r['target'] if t is not None):.2f} "
                  f"cones {r['cones'] if r['cones'] is None else round(r['cones'], 2)} "
                  f"step {r['step'] if r['step'] is None else round(r['step'], 2)} "
                  f"removed {r['removed'] if r['removed'] is None else round(r['removed'], 2)} -> {r['level']}",
                  flush=True)

    cases = [demo_case(n, a, ctx) for n in ("room", "garden")] + [real_case(p, a, ctx) for p in a.real]
    rng = np.random.default_rng(2026 + frame_seed)
    for case in cases:
        record(case.name, "correct", "as it is", case.verdict(case.pre, case.reference, None, ctx))
        for px in MISDRAWN:
            drawn = Case(case.name, case.pre, case.target, case.reference, case.cams, misdrawn(case.masks, px))
            record(case.name, "correct", f"masks {px:+d} px", drawn.verdict(case.pre, case.reference, None, ctx))
        if case.name in ("room", "garden"):
            pts = case.pre.means[np.random.default_rng(0).choice(case.pre.n, min(3000, case.pre.n), replace=False)]
            gsplat = gsplat_normalization(list(case.cams.values()), pts)  # the cameras' world -> gsplat's
            moved, moved_ref = moved_gaussians(case.pre, gsplat), moved_gaussians(case.reference, gsplat)
            record(case.name, "correct", "gsplat's world, frame declared", case.verdict(moved, moved_ref, gsplat, ctx))
            unmoved = Frame.from_matrix(np.linalg.inv(gsplat.m), "gsplat's world, cameras as they are")
            record(case.name, "wrong" if case.object_iou(unmoved, ctx) < IOU_WRONG else "still fits",
                   "gsplat's world, not declared", case.verdict(case.pre, case.reference, unmoved, ctx),
                   case.object_iou(unmoved, ctx))
        for k in range(a.wrong):
            m = random_similarity(rng, centres=case.centres, radius=case.radius, scales=SCALES, any_rotation=True)
            frame = Frame.from_matrix(m, f"random {k}")
            iou = case.object_iou(frame, ctx)
            record(case.name, "wrong" if iou < IOU_WRONG else "still fits", f"random {k}",
                   case.verdict(case.pre, case.reference, frame, ctx), iou)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    print()
    print_confusion(rows)


def print_confusion(rows) -> None:
    """The confusion table: per scene and truth, how many cases got each verdict."""
    count = Counter((r["scene"], r["truth"], r["level"]) for r in rows)
    keys = list(dict.fromkeys((r["scene"], r["truth"]) for r in rows))
    print("| scene | frame | cases | " + " | ".join(VERDICTS) + " |")
    print("| --- | --- | --- | " + " | ".join("---" for _ in VERDICTS) + " |")
    for scene, truth in keys:
        n = sum(count[scene, truth, v] for v in VERDICTS)
        print(f"| {scene} | {truth} | {n} | " + " | ".join(str(count[scene, truth, v]) for v in VERDICTS) + " |")
    for truth in ("correct", "wrong", "still fits"):
        n = sum(count[s, t, v] for s, t in keys if t == truth for v in VERDICTS)
        if n:
            print(f"| all | {truth} | {n} | "
                  + " | ".join(str(sum(count[s, t, v] for s, t in keys if t == truth)) for v in VERDICTS) + " |")


if __name__ == "__main__":
    main()
