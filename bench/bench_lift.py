"""Cost of target lifting and of rendering target masks against a plain render.

The scene is bench_render.py's synthetic one (uniform in the frustum,
log-normal scales, bimodal opacities, SH degree 3); the views turn a little
about the scene's centre; each view's target mask is a central ellipse.  Per
set of views it times, with the device waited on at the end of each:

* plain: :meth:`Renderer.render_device` of every view (the renderer alone);
* lift: :meth:`MaskLifter.add_view` of every view plus reading the weights;
* mask: :meth:`TargetMaskRenderer.device` of every view (the lifted target's
  masks).

and prints the medians and the ratios lift / plain and mask / plain (goal:
each <= 1.5).  Mask uploads are part of lifting (they are part of
the work).  The full case is 1M Gaussians, 24 views, 1920x1080;
on a shared 2-core lavapipe machine use a smaller one (``--n``, ``--views``,
``--width``, ``--height``) and say so.  The defaults are the full case (on a
GPU: ``python bench/bench_lift.py``; the last line says how long the whole
run took, the 1M-Gaussian scene's generation, about 7 s of numpy, included).

Usage:  python bench/bench_lift.py [--n 1000000] [--views 24] [--width 1920] [--height 1080] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_render import synthetic_scene  # noqa: E402
from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io.camera import Camera  # noqa: E402
from r360gpu.lift import MaskLifter, TargetMaskRenderer  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402


def cameras(views: int, width: int, height: int) -> list[Camera]:
    focal = 1000.0 * width / 1920
    out = []
    for i in range(views):
        a = np.deg2rad(-6 + 12 * i / max(views - 1, 1))
        c, s = np.cos(a), np.sin(a)
        R = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])
        pivot = np.array([0.0, 0.0, 11.0])  # turn about the middle of the scene's depth range
        out.append(Camera(R=R, t=pivot - R @ pivot, fx=focal, fy=focal, cx=width / 2, cy=height / 2,
                          width=width, height=height, name=f"v{i:02d}"))
    return out


def ellipse(width: int, height: int) -> np.ndarray:
    y, x = np.mgrid[0:height, 0:width]
    return ((x - width / 2) / (0.2 * width)) ** 2 + ((y - height / 2) / (0.25 * height)) ** 2 <= 1


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    ctx = get_context()
    scene = synthetic_scene(args.n)
    cams = cameras(args.views, args.width, args.height)
    mask = ellipse(args.width, args.height)
    print(f"adapter: {ctx.describe().get('name', ctx.adapter_info['name'])}; {args.n} Gaussians, {args.views} views "
          f"at {args.width}x{args.height}, median of {args.repeat}")

    plain = Renderer(scene, ctx=ctx)

    def run_plain():
        for cam in cams:
            img = plain.render_device(cam)
            ctx.read(img.buffer, np.uint32, 1)
            img.buffer.destroy()

    lifter = MaskLifter(scene, ctx=ctx)

    def run_lift():
        lifter.reset()
        for cam in cams:
            lifter.add_view(cam, mask)
        return lifter.weights()

    w_in, w_out = run_lift()
    target = (w_in >= 0.5 * (w_in + w_out)) & (w_in + w_out >= 0.05)
    masks = TargetMaskRenderer(scene, target, ctx=ctx)

    def run_mask():
        for cam in cams:
            img = masks.device(cam)
            ctx.read(img.buffer, np.uint32, 1)
            img.buffer.destroy()

    run_plain()  # warm-up: pipelines compiled, scratch buffers sized
    run_mask()
    t_plain = median_time(run_plain, args.repeat)
    t_lift = median_time(run_lift, args.repeat)
    t_mask = median_time(run_mask, args.repeat)
    print(f"target: {int(target.sum())} of {args.n} Gaussians")
    print(f"plain render  {t_plain:8.3f} s  ({1000 * t_plain / args.views:.1f} ms/view)")
    print(f"lift          {t_lift:8.3f} s  ratio lift/plain {t_lift / t_plain:.2f} (goal <= 1.5)")
    print(f"target masks  {t_mask:8.3f} s  ratio mask/plain {t_mask / t_plain:.2f} (goal <= 1.5)")
    for r in (plain, lifter, masks):
        r.release()
    print(f"whole run {time.perf_counter() - t_start:.1f} s (scene generation and warm-ups included)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
