"""The renderer's two sort paths in one run: WGSL radix sort vs the host sort (issue 13).

On a CPU adapter the renderer sorts depth keys and tile keys in numpy
(``render.sort.host_argsort``; ``GpuContext.kernel_backend("sort")``).  This
renders the same frames with ``R360GPU_SORT=gpu`` and ``=cpu`` and prints, per
path, the wall time and the process CPU time per frame and the ``sort`` stage
(medians over alternating rounds)
(timed with device waits), the ratio, and whether the images are bit-equal.

Scenes are bench_render.py's synthetic scene; the default size is the demo's
(75k Gaussians at 480x360, about what ``r360gpu demo`` renders 224 times).

Usage:  python bench/bench_render_sort.py [--sizes 75000 --width 480 --height 360] [--frames 8] [--rounds 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_render import FOCAL, HEIGHT, WIDTH, camera, synthetic_scene  # noqa: E402
from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402


def run(ctx, scene, cam, backend: str, frames: int) -> dict:
    os.environ["R360GPU_SORT"] = backend
    renderer = Renderer(scene, ctx=ctx, timed=True)
    renderer.render(cam)  # warm-up: pipelines, buffers
    sort = []
    for _ in range(frames):
        renderer.render(cam)
        sort.append(renderer.stats.times["sort"])
    renderer.timed = False
    c0, t0 = time.process_time(), time.perf_counter()
    for _ in range(frames):
        out = renderer.render(cam)
    wall, cpu = (time.perf_counter() - t0) / frames, (time.process_time() - c0) / frames
    renderer.release()
    return dict(wall=wall, cpu=cpu, sort=float(np.median(sort)), out=out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[75_000])
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds of both paths (medians reported)")
    args = ap.parse_args(argv)
    ctx = get_context()
    d = ctx.describe()
    print(f"adapter: {d['name']} ({d['adapter_type']}); CPU cores: {os.cpu_count()}; "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    # bench_render's camera is 1920x1080 with FOCAL; scale the focal length with the width
    f = FOCAL * args.width / WIDTH
    print(f"{'N':>9} {'size':>9} {'path':>5} {'wall ms':>8} {'CPU ms':>8} {'sort ms':>8}")
    for n in args.sizes:
        scene = synthetic_scene(n)
        cam = camera(args.width, args.height, f)
        # alternate the paths for --rounds rounds and keep each one's median: a 2-core machine's
        # frame times wander by tens of per cent between consecutive runs
        rounds = {"gpu": [], "cpu": []}
        for _ in range(args.rounds):
            for b in rounds:
                rounds[b].append(run(ctx, scene, cam, b, args.frames))
        res = {b: {k: float(np.median([r[k] for r in rs])) for k in ("wall", "cpu", "sort")} | {"out": rs[-1]["out"]}
               for b, rs in rounds.items()}
        for b, r in res.items():
            print(f"{n:>9} {args.width}x{args.height:<4} {b:>5} {r['wall'] * 1e3:8.1f} {r['cpu'] * 1e3:8.1f} "
                  f"{r['sort'] * 1e3:8.1f}")
        g, c = res["gpu"], res["cpu"]
        same = all(np.array_equal(getattr(g["out"], k), getattr(c["out"], k))
                   for k in ("rgb", "alpha", "depth", "median_depth"))
        print(f"  host sort vs WGSL sort: wall {g['wall'] / c['wall']:.2f}x, CPU {g['cpu'] / c['cpu']:.2f}x, "
              f"sort stage {g['sort'] / c['sort']:.2f}x; images bit-equal: {same}")
    os.environ.pop("R360GPU_SORT", None)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
