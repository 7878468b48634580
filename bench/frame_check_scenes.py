"""The frame check's readings on the demo's scenes, aligned and in gsplat's normalised world.

Usage:
    python bench/frame_check_scenes.py [--size WxH] [--views N] [--detail D] [--seed S]

Defaults are the demo's (480x360, 16 views, full detail).  Per scene (the synthetic room and
garden) it prints the frame check's readings (r360gpu.metrics.frame_check.check_views) for
pre as generated, and for pre as gsplat's simple_trainer would save it (normalize_world_space,
recomputed from the cameras and the splat centres as the sparse points) scored with and
without ``frame = "gsplat"``.  The moved world is rendered by moving the cameras the other way
(what a misframed camera sees), so the Gaussians stay as generated.  These are the tables of
docs/your-scene.md ("The check"); tests/test_frame_check_class.py checks the whole class.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io.frames import Frame, gsplat_normalization  # noqa: E402
from r360gpu.metrics import frame_check  # noqa: E402
from r360gpu.render.sources import SceneSource  # noqa: E402
from r360gpu.synthetic import make_scene  # noqa: E402
from r360gpu.synthetic.masks import target_masks  # noqa: E402

from common import header  # noqa: E402


def readings(scene, masks, frame, ctx) -> frame_check.FrameVerdict:
    cams = {c.name: c for c in scene.cameras}
    src = SceneSource(scene.pre, ctx=ctx, frame=frame)
    try:
        views = []
        for v in frame_check.checked_views([v for v in cams if masks[v].any()]):
            img = src.images(v, cams[v])
            views.append((v, cams[v], img.alpha, img.depth, masks[v]))
        return frame_check.check_views(views)
    finally:
        src.release()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="480x360")
    ap.add_argument("--views", type=int, default=16)
    ap.add_argument("--detail", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    w, h = (int(x) for x in a.size.split("x"))
    header(f"frame check on the demo's scenes ({w}x{h}, {a.views} views, detail {a.detail}, seed {a.seed}; "
           f"{time.strftime('%Y-%m-%d')})")
    ctx = get_context()
    print("| scene | frames | image covered | target covered | cone agreement | outline step | agreement | verdict |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in ("room", "garden"):
        scene = make_scene(name, seed=a.seed, n_views=a.views, width=w, height=h, detail=a.detail)
        masks = target_masks(scene, ctx=ctx)
        points = scene.pre.means[np.random.default_rng(0).choice(scene.pre.n, min(3000, scene.pre.n), replace=False)]
        gsplat = gsplat_normalization(list(scene.cameras), points)  # the cameras' world -> gsplat's
        # pre saved in gsplat's world: with frame = "gsplat" the cameras follow it (the scene as
        # generated); with the cameras as they are, they see the world moved by the inverse
        unmoved = Frame.from_matrix(np.linalg.inv(gsplat.m), "gsplat's world, cameras as they are")
        for label, frame in (("as generated, or in gsplat's world with `frame = \"gsplat\"`", None),
                             ("gsplat's world, cameras as they are", unmoved)):
            v = readings(scene, masks, frame, ctx)
            cov = [x.coverage for x in v.views]
            tgt = [x.target for x in v.views if x.target is not None]
            steps = [x.step for x in v.views if x.step is not None]
            fmt = lambda x: "-" if x is None else f"{x:.2f}"  # noqa: E731
            print(f"| {name} | {label} | {100 * min(cov):.0f}-{100 * max(cov):.0f}% | "
                  f"{100 * min(tgt):.0f}-{100 * max(tgt):.0f}% | {fmt(v.cones)} | "
                  f"{fmt(float(np.median(steps)) if steps else None)} | {fmt(v.agreement)} | {v.level} |", flush=True)


if __name__ == "__main__":
    main()
