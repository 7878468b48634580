"""Generate the built-in synthetic benchmark into a folder and print how long it took.

Times per scene: building the Gaussians and cameras (numpy), and writing the
bundle (target-mask renders on the GPU, the .ply / camera / mask files, the
method edits).  ``r360gpu demo`` generates this benchmark and scores it, all
within 10 minutes on a 2-core machine, so generation should stay well under
a minute.

Usage:  python bench/make_synthetic.py OUT [--seed 0] [--views 20] [--size 480 360] [--detail 1.0]
                                           [--scenes room garden [garden_open]] [--methods ...]
                                           [--cameras colmap|transforms]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from r360gpu.gpu import get_context
from r360gpu.synthetic import CAMERA_FORMATS, DEFAULT_METHODS, METHODS, SCENES, make_scene, write_bundle


def _size(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="folder to write the bundles into (one sub-folder per scene)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--size", type=int, nargs=2, default=(480, 360), metavar=("W", "H"))
    ap.add_argument("--detail", type=float, default=1.0, help="Gaussian count scale (1.0: 50k-80k per scene)")
    ap.add_argument("--scenes", nargs="+", default=["room", "garden"], choices=list(SCENES),
                    help="scenes to write (default: room garden; garden_open, the bench in open space, by name)")
    ap.add_argument("--methods", nargs="+", default=list(DEFAULT_METHODS), choices=list(METHODS),
                    help="simulated methods (default: all but backside, which only --orbit can see)")
    ap.add_argument("--cameras", default="colmap", choices=CAMERA_FORMATS)
    args = ap.parse_args()

    t0 = time.perf_counter()
    ctx = get_context()
    t_ctx = time.perf_counter() - t0
    print(f"# synthetic benchmark -> {args.out}")
    d = ctx.describe()
    print(f"adapter: {d['name']} ({d['adapter_type']}, {d['backend']}); GPU context {t_ctx:.2f} s")
    print(f"{'scene':11s} {'pre':>8s} {'target':>7s} {'hidden':>7s} {'build s':>8s} {'write s':>8s} {'MiB':>6s}")
    for name in args.scenes:
        t = time.perf_counter()
        scene = make_scene(name, seed=args.seed, n_views=args.views, width=args.size[0], height=args.size[1],
                           detail=args.detail)
        t_build = time.perf_counter() - t
        t = time.perf_counter()
        folder = write_bundle(scene, args.out / name, seed=args.seed, methods=args.methods,
                              camera_format=args.cameras, ctx=ctx)
        t_write = time.perf_counter() - t
        print(f"{name:11s} {scene.pre.n:8d} {scene.target.n:7d} {int(scene.hidden.sum()):7d} {t_build:8.2f} "
              f"{t_write:8.2f} {_size(folder) / 2**20:6.1f}")
    print(f"total {time.perf_counter() - t0:.2f} s")


if __name__ == "__main__":
    main()
