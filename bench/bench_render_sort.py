"""The renderer's two sort paths in one run: WGSL radix sort vs the host sort; keys/s.

On a CPU adapter the renderer sorts depth keys and tile keys in numpy
(``render.sort.host_argsort``; ``GpuContext.kernel_backend("sort")``).  This
renders the same frames with ``R360GPU_SORT=gpu`` and ``=cpu`` and prints, per
path, the wall time and the process CPU time per frame and the ``sort`` stage
(medians over alternating rounds)
(timed with device waits), the ratio, and whether the images are bit-equal.

Scenes are bench_render.py's synthetic scene; the default size is the demo's
(75k Gaussians at 480x360, about what ``r360gpu demo`` renders 224 times).

Then the WGSL radix sort alone, per variant, in keys/s (wall time of the
recorded sort and its wait, and the device time of its passes from timestamp
queries where the adapter has them):

* ``1M pairs``: 1,000,000 random (u32 key, u32 value) pairs by all 32 bits,
  the size of wgpu_sort's published figure (1M pairs in 317 us on an RTX
  A5000; a figure to compare only with a GPU run of this bench);
* the renderer's two exact sorts of the last frame: its N depth keys by 32
  bits, then its K duplicated keys by the tile id's bits (stable, so each
  tile's list stays in depth order);
* the packed alternative (VkSplat, luma.gl): the same K keys by one 32-bit
  key of tile id and quantised depth.  It sorts K keys by 32 bits where the
  renderer sorts N by 32 and K by ``ceil(log2(tiles))``, and it is not exact:
  Gaussians whose depths share a quantisation bucket blend in index order
  instead of depth order (tests/test_render_recording.py checks the
  renderer's order).

Usage:  python bench/bench_render_sort.py [--sizes 75000 --width 480 --height 360] [--frames 8] [--rounds 5]
                                          [--pairs 1000000] [--sort-reps 3] [--no-frames]
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
from r360gpu.render.project import tile_grid  # noqa: E402
from r360gpu.render.scratch import Scratch  # noqa: E402
from r360gpu.render.sort import VARIANTS, radix_sort, sorted_bits  # noqa: E402


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


def sort_rate(ctx, keys: np.ndarray, bits: int, variant: str, reps: int) -> dict:
    """Median wall seconds of one WGSL radix sort of (keys, arange) by ``bits`` bits, recorded,
    submitted and waited for (the inputs re-uploaded and waited for before each), and the device
    seconds of its passes (timestamp queries; None without them)."""
    n = int(keys.size)
    vals = np.arange(n, dtype=np.uint32)
    kb, vb = ctx.buffer(keys), ctx.buffer(vals)
    scratch = Scratch(ctx)
    walls, device = [], None
    for rep in range(reps + 2):  # the first: pipelines and scratch buffers; the last: device time
        ctx.write(kb, keys)
        ctx.write(vb, vals)
        ctx.read(kb, np.uint32, 1)
        profiled = rep == reps + 1 and ctx.profile_begin()
        t = time.perf_counter()
        enc = ctx.encoder()
        ks, _ = radix_sort(ctx, enc, kb, vb, n, bits, scratch, "bench", variant=variant)
        ctx.submit(enc)
        ctx.read(ks, np.uint32, 1)
        if profiled:
            device = sum(secs for _, secs in ctx.profile_end().values())
        elif 0 < rep <= reps:
            walls.append(time.perf_counter() - t)
    got = ctx.read(ks, np.uint32, n)
    mask = np.uint32((1 << sorted_bits(bits)) - 1) if sorted_bits(bits) < 32 else np.uint32(0xFFFFFFFF)
    ok = bool(np.all(np.diff((got & mask).astype(np.int64)) >= 0))
    scratch.release()
    kb.destroy()
    vb.destroy()
    return dict(n=n, bits=bits, wall=float(np.median(walls)), device=device, sorted=ok)


def print_sort_rates(ctx, pairs: int, frame: dict | None, reps: int) -> None:
    """keys/s of the WGSL sort: ``pairs`` random pairs, and the last frame's sorts against the packed one."""
    rng = np.random.default_rng(37)
    cases = [("1M pairs" if pairs == 1_000_000 else f"{pairs} pairs", rng.integers(0, 2**32, pairs, dtype=np.uint64)
              .astype(np.uint32), 32)]
    if frame:
        n, k, tiles = frame["n"], frame["keys"], frame["tiles"]
        tile_bits = (tiles - 1).bit_length()
        depth = rng.uniform(2.0, 20.0, n).astype(np.float32).view(np.uint32)
        tile_ids = rng.integers(0, tiles, k, dtype=np.uint64).astype(np.uint32)
        packed = (tile_ids << np.uint32(32 - tile_bits)) | rng.integers(0, 2**(32 - tile_bits), k, dtype=np.uint64
                                                                         ).astype(np.uint32) if tile_bits else tile_ids
        cases += [("depth keys", depth, 32), ("tile ids", tile_ids, tile_bits), ("packed tile+depth", packed, 32)]
    timed = "timestamp-query" in ctx.features
    print()
    print(f"WGSL radix sort alone (median of {reps}; device = sum of its passes' timestamp queries"
          f"{'' if timed else ': this adapter has none'}):")
    print(f"{'variant':>8} {'case':>18} {'keys':>9} {'bits':>4} {'wall ms':>9} {'Mkeys/s':>9} {'device ms':>9} "
          f"{'Mkeys/s':>9} {'sorted':>6}")
    for variant in VARIANTS:
        res = {}
        for name, keys, bits in cases:
            r = res[name] = sort_rate(ctx, keys, bits, variant, reps)
            dev = (f"{1e3 * r['device']:9.3f} {r['n'] / r['device'] / 1e6:9.1f}" if r["device"]
                   else f"{'-':>9} {'-':>9}")
            print(f"{variant:>8} {name:>18} {r['n']:>9} {bits:>4} {1e3 * r['wall']:9.2f} "
                  f"{r['n'] / r['wall'] / 1e6:9.1f} {dev} {str(r['sorted']):>6}")
        if frame:
            ours = res["depth keys"]["wall"] + res["tile ids"]["wall"]
            packed = res["packed tile+depth"]["wall"]
            line = (f"  {variant}: the renderer's exact sorts (N={frame['n']} by 32 bits + K={frame['keys']} by "
                    f"{tile_bits} bits) {1e3 * ours:.1f} ms wall vs the packed 32-bit sort of K keys "
                    f"{1e3 * packed:.1f} ms ({packed / ours:.2f}x)")
            if all(res[c]["device"] for c in ("depth keys", "tile ids", "packed tile+depth")):
                dev_ours = res["depth keys"]["device"] + res["tile ids"]["device"]
                line += (f"; device {1e3 * dev_ours:.2f} vs {1e3 * res['packed tile+depth']['device']:.2f} ms "
                         f"({res['packed tile+depth']['device'] / dev_ours:.2f}x)")
            print(line)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[75_000])
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=5, help="alternating rounds of both paths (medians reported)")
    ap.add_argument("--pairs", type=int, default=1_000_000, help="random pairs of the keys/s line (wgpu_sort: 1M)")
    ap.add_argument("--sort-reps", type=int, default=3, help="timed repetitions of each sort alone")
    ap.add_argument("--no-frames", action="store_true", help="only the sort alone on the first size's frame")
    args = ap.parse_args(argv)
    ctx = get_context()
    d = ctx.describe()
    print(f"adapter: {d['name']} ({d['adapter_type']}); CPU cores: {os.cpu_count()}; "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    # bench_render's camera is 1920x1080 with FOCAL; scale the focal length with the width
    f = FOCAL * args.width / WIDTH
    frame = None
    if not args.no_frames:
        print(f"{'N':>9} {'size':>9} {'path':>5} {'wall ms':>8} {'CPU ms':>8} {'sort ms':>8}")
    for n in args.sizes:
        scene = synthetic_scene(n)
        cam = camera(args.width, args.height, f)
        if frame is None:
            r = Renderer(scene, ctx=ctx)
            r.render(cam)
            gx, gy = tile_grid(args.width, args.height)
            frame = dict(n=n, keys=r.stats.keys, tiles=gx * gy)
            r.release()
        if args.no_frames:
            break
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
    print_sort_rates(ctx, args.pairs, frame, args.sort_reps)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
