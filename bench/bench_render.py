"""Benchmark of the WGSL 3DGS renderer: ms per frame and per stage, against the numpy oracle.

Renders a synthetic scene at 1920x1080 with 100k and 1M Gaussians and prints
milliseconds per frame and per stage (project, sort = depth sort + binning +
tile sort + ranges, rasterise; timed by waiting for the device after each
stage), the same frame without the per-stage waits (``device``: the image left
on the device, as a viewer or a GPU probe uses it; ``+readback``: read back as
numpy arrays, ``Renderer.render``), the host's waits for the device per frame,
the numpy oracle on a small case for a speed ratio, and the rasteriser's
throughput against a physical-limit estimate for this CPU.

``--variants serial blocks`` renders every size with the depth and tile sorts
in WGSL (``R360GPU_SORT=gpu``, what a GPU adapter runs) once per radix sort
variant (``r360gpu.render.sort.VARIANTS``; ``serial`` is the CPU-tuned peer,
``blocks`` the GPU one), alternating them on one uploaded scene, and prints
the ratios and whether the images are bit-equal.

``--gpu-times`` renders one more device frame per size and variant with every
compute pass timed on the device (timestamp queries) and prints the device
milliseconds per kernel, their sum, and the rest of the frame's wall time
(host recording, submissions and waits).

``--host-recording`` measures instead what the host spends recording and
submitting one frame: frames of one camera rendered to the device
with the sorts recorded as WGSL passes (``R360GPU_SORT=gpu``, the blocks
variant: what a GPU adapter records), the main thread's CPU seconds per frame
outside its waits for the device (``time.thread_time``, so the load of other
processes and lavapipe's own threads do not count), in a fresh process per
side and round; ``--peer ROOT`` runs the same measurement on the r360gpu of
another checkout (e.g. main's, before frames of one shape reused their bind
groups and uniform buffers) in alternating rounds and prints the ratio.

Synthetic scene: means uniform inside the camera frustum at depths 2..20,
per-axis scales log-normal (median 0.02, sigma 0.8 in log space), random
rotations, opacities sigmoid(N(0, 2)) (bimodal, like trained scenes), SH
degree 3.

Usage:  python bench/bench_render.py [--sizes 100000 1000000] [--repeat 3] [--no-oracle]
                                     [--variants serial blocks] [--rounds 2] [--gpu-times]
        python bench/bench_render.py --host-recording [--sizes 65000] [--size 480x360] [--repeat 20]
                                     [--rounds 3] [--peer /path/to/other/checkout]
The 1M case renders 3 x ``--repeat`` frames per variant and round; keep it small on a shared machine.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

from r360gpu.gpu import get_context  # noqa: E402
from r360gpu.io.camera import Camera  # noqa: E402
from r360gpu.io.gaussians import Gaussians  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402
from r360gpu.render.rasterize import image_to_numpy  # noqa: E402
from r360gpu.render.sort import VARIANT_ENV, VARIANTS  # noqa: E402

WIDTH, HEIGHT, FOCAL = 1920, 1080, 1000.0
#: Goal: 1M Gaussians at 1080p in at most this many seconds on lavapipe.
GOAL_1M_S = 2.0
#: Floating-point operations per evaluated pixel-Gaussian pair in the
#: rasteriser's inner loop (offset 2, quadratic form 8, exp ~10, min/compares
#: 4, transmittance and blend of colour, weight and depth ~12).
FLOPS_PER_PAIR = 36


def synthetic_scene(n: int, seed: int = 0) -> Gaussians:
    rng = np.random.default_rng(seed)
    z = rng.uniform(2.0, 20.0, n)
    x = rng.uniform(-1, 1, n) * z * (WIDTH / 2) / FOCAL
    y = rng.uniform(-1, 1, n) * z * (HEIGHT / 2) / FOCAL
    means = np.stack([x, y, z], 1)
    scales = np.exp(rng.normal(np.log(0.02), 0.8, (n, 3)))
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    opacities = 1 / (1 + np.exp(-rng.normal(0.0, 2.0, n)))
    sh = rng.normal(0, 0.1, (n, 16, 3))
    sh[:, 0, :] = rng.normal(0, 1.0, (n, 3))
    return Gaussians(means, scales, quats, opacities, sh)


def camera(width=WIDTH, height=HEIGHT, focal=FOCAL) -> Camera:
    return Camera(R=np.eye(3), t=np.zeros(3), fx=focal, fy=focal, cx=width / 2, cy=height / 2,
                  width=width, height=height, name="bench")


def peak_flops(seconds: float = 1.0) -> float:
    """Float32 FLOP/s of this CPU from a BLAS sgemm (2 n^3 flops, FMA counted as 2)."""
    n = 1024
    a = np.random.default_rng(0).random((n, n), dtype=np.float32)
    b = a.copy()
    a @ b
    best, t_end = 0.0, time.perf_counter() + seconds
    while time.perf_counter() < t_end:
        t = time.perf_counter()
        a @ b
        best = max(best, 2 * n**3 / (time.perf_counter() - t))
    return best


class CountWaits:
    """Counts the host's reads from the device (each one waits for the queue) while active."""

    def __init__(self, ctx):
        self.ctx, self.count = ctx, 0

    def __enter__(self):
        read = self.ctx.read

        def counted(*args, **kwargs):
            self.count += 1
            return read(*args, **kwargs)

        self.ctx.read = counted
        return self

    def __exit__(self, *exc):
        del self.ctx.read  # back to the class's method


def time_readbacks(ctx, image, width: int, height: int, stride: int, repeat: int) -> dict:
    """Median seconds of the image's numpy read-back with the colour interleaved on the device
    and on the host (the peer: the previous way, and CPU adapters' default), alternated; bit-equality."""
    times = {"gpu": [], "cpu": []}
    got = {}
    for _ in range(repeat):
        for where, acc in times.items():
            os.environ["R360GPU_RENDER_INTERLEAVE"] = where
            t = time.perf_counter()
            got[where] = image_to_numpy(ctx, image, width, height, stride)
            acc.append(time.perf_counter() - t)
    os.environ.pop("R360GPU_RENDER_INTERLEAVE")
    same = all(np.array_equal(got["gpu"][k].view(np.uint32), got["cpu"][k].view(np.uint32)) for k in got["gpu"])
    return dict(readback_s=float(np.median(times["gpu"])), readback_peer_s=float(np.median(times["cpu"])),
                readback_same=same)


def frames(renderer, cam, repeat: int, variant: str | None, gpu_times: bool = False) -> dict:
    """Stage times (timed frames), device-resident and read-back frame times, waits per frame."""
    if variant:
        os.environ[VARIANT_ENV] = variant
    ctx = renderer.ctx
    renderer.timed = renderer.count_work = True
    renderer.render(cam)  # warm-up: pipelines, buffers
    stages = []
    for _ in range(repeat):
        renderer.render(cam)
        stages.append(dict(renderer.stats.times))
    stats = renderer.stats
    renderer.timed = renderer.count_work = False
    dev = renderer.render_device(cam)
    image = dev.buffer  # the image buffer every device frame reuses
    ctx.read(image, np.uint32, 1)
    readbacks = time_readbacks(ctx, image, dev.width, dev.height, dev.plane_stride, repeat)
    device, readback = [], []
    with CountWaits(ctx) as waits:
        for _ in range(repeat):
            t = time.perf_counter()
            renderer.render_device(cam, image=image)
            ctx.read(image, np.uint32, 1)  # wait for the frame (4 bytes: no readback cost)
            device.append(time.perf_counter() - t)
    device_waits = waits.count / repeat - 1  # less the read that waits for the frame
    kernels, profiled_s = {}, 0.0
    if gpu_times and ctx.profile_begin():
        t = time.perf_counter()
        renderer.render_device(cam, image=image)
        ctx.read(image, np.uint32, 1)
        profiled_s = time.perf_counter() - t
        kernels = ctx.profile_end()
    with CountWaits(ctx) as waits:
        for _ in range(repeat):
            t = time.perf_counter()
            out = renderer.render(cam)
            readback.append(time.perf_counter() - t)
    med = {k: float(np.median([s[k] for s in stages])) for k in stages[0]}
    return dict(stages=med, device_s=float(np.median(device)), frame_s=float(np.median(readback)),
                device_waits=device_waits, frame_waits=waits.count / repeat, keys=stats.keys,
                kernels=kernels, profiled_s=profiled_s, **readbacks,
                windows=stats.windows, evaluated=stats.evaluated, blended=stats.blended, out=out,
                coverage=float((out.alpha >= 0.5).mean()))


def bench_size(ctx, n: int, repeat: int, width: int = WIDTH, height: int = HEIGHT,
               variants: tuple = (None,), rounds: int = 1, gpu_times: bool = False) -> dict:
    """Per variant (None: the adapter's default sort path) the medians of ``rounds`` alternating rounds."""
    scene = synthetic_scene(n)
    cam = camera(width, height, FOCAL * width / WIDTH)
    t = time.perf_counter()
    renderer = Renderer(scene, ctx=ctx)
    upload = time.perf_counter() - t
    runs = {v: [] for v in variants}
    for _ in range(rounds):
        for v in variants:
            runs[v].append(frames(renderer, cam, repeat, v, gpu_times))
    renderer.release()
    out = {}
    for v, rs in runs.items():
        r = dict(rs[-1])
        for k in ("device_s", "frame_s", "readback_s", "readback_peer_s"):
            r[k] = float(np.median([x[k] for x in rs]))
        r["stages"] = {k: float(np.median([x["stages"][k] for x in rs])) for k in rs[0]["stages"]}
        out[v] = dict(r, n=n, upload_s=upload, variant=v)
    return out


def bench_oracle(ctx) -> dict:
    import render_oracle

    n, w, h, f = 5000, 320, 180, FOCAL / 6
    scene = synthetic_scene(n, seed=1)
    cam = camera(w, h, f)
    renderer = Renderer(scene, ctx=ctx)
    renderer.render(cam)
    t = time.perf_counter()
    gpu = renderer.render(cam)
    gpu_s = time.perf_counter() - t
    renderer.release()
    t = time.perf_counter()
    ref = render_oracle.render(scene, cam)
    oracle_s = time.perf_counter() - t
    return dict(n=n, size=f"{w}x{h}", gpu_s=gpu_s, oracle_s=oracle_s,
                max_rgb_err=float(np.abs(gpu.rgb - ref["rgb"]).max()))


def print_kernel_times(results: list, supported: bool) -> None:
    """Device ms per kernel of each result's profiled frame, their sum and the frame's other time."""
    print()
    if not supported:
        print("device time per kernel: this adapter has no timestamp-query feature")
        return
    for r in results:
        k = r["kernels"]
        busy = sum(secs for _, secs in k.values())
        tag = f", {r['variant']} sort" if r["variant"] else ""
        print(f"device time per kernel, one frame (image on the device), N={r['n']}{tag}: "
              f"{1e3 * busy:.2f} ms on the device of {1e3 * r['profiled_s']:.2f} ms wall; "
              f"the other {1e3 * (r['profiled_s'] - busy):.2f} ms: host recording, submissions, waits")
        for label, (count, secs) in sorted(k.items(), key=lambda kv: -kv[1][1]):
            print(f"    {label:<32} {count:>4} passes {1e3 * secs:>9.3f} ms")


def host_recording(n: int, width: int, height: int, frames: int) -> dict:
    """Main-thread CPU seconds per device frame outside the waits for the device (this process's
    r360gpu), dispatches per frame, and (where the renderer keeps them) bind groups and uniform
    buffers created per frame."""
    os.environ["R360GPU_SORT"] = "gpu"
    os.environ[VARIANT_ENV] = "blocks"
    ctx = get_context()
    renderer = Renderer(synthetic_scene(n), ctx=ctx)
    cam = camera(width, height, FOCAL * width / WIDTH)
    image = renderer.render_device(cam).buffer
    for _ in range(2):  # warm-up: pipelines, scratch buffers, and (where kept) the frame's device objects
        renderer.render_device(cam, image=image)
        ctx.read(image, np.uint32, 1)
    read, dispatch = ctx.read, ctx.dispatch
    waited, dispatches = [0.0], [0]

    def timed_read(*args, **kwargs):
        t = time.thread_time()
        try:
            return read(*args, **kwargs)
        finally:
            waited[0] += time.thread_time() - t

    def counted_dispatch(*args, **kwargs):
        dispatches[0] += 1
        return dispatch(*args, **kwargs)

    ctx.read, ctx.dispatch = timed_read, counted_dispatch
    kept = getattr(renderer, "frames", None)
    before = dict(kept.counts) if kept else None
    t = time.thread_time()
    for _ in range(frames):
        renderer.render_device(cam, image=image)
        ctx.read(image, np.uint32, 1)
    host = (time.thread_time() - t - waited[0]) / frames
    del ctx.read, ctx.dispatch
    out = dict(host_s=host, dispatches=dispatches[0] / frames, keys=renderer.stats.keys,
               module=os.path.dirname(sys.modules["r360gpu"].__file__))
    if kept:
        out.update({k: (kept.counts[k] - before[k]) / frames for k in ("groups_created", "uniforms_created")})
    renderer.release()
    return out


def host_recording_child(root: str, python: str, n: int, size: tuple, frames: int) -> dict:
    """:func:`host_recording` in a fresh process importing the r360gpu of checkout ``root``."""
    env = dict(os.environ, PYTHONPATH=root)
    cmd = [python, os.path.abspath(__file__), "--host-child", str(n), f"{size[0]}x{size[1]}", str(frames)]
    res = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} (in {root}) failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def bench_host_recording(sizes, size: tuple, frames: int, rounds: int, peer: str | None) -> None:
    ours = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sides = {"ours": (ours, sys.executable)}
    if peer:
        python = os.path.join(peer, ".venv", "bin", "python")
        sides["peer"] = (peer, python if os.path.exists(python) else sys.executable)
    print(f"host recording per frame, {size[0]}x{size[1]}, {frames} frames of one camera per process, "
          f"medians of {rounds} alternating rounds (main-thread CPU outside device waits; WGSL sorts, blocks variant)")
    print(f"{'N':>9} {'side':>5} {'host ms':>8} {'dispatches':>10} {'groups new':>10} {'uniforms new':>12} {'keys':>9}  r360gpu")
    for n in sizes:
        runs = {k: [] for k in sides}
        for _ in range(rounds):
            for side, (root, python) in sides.items():
                runs[side].append(host_recording_child(root, python, n, size, frames))
        med = {k: float(np.median([r["host_s"] for r in rs])) for k, rs in runs.items()}
        for side, rs in runs.items():
            r = rs[-1]
            fmt = (lambda key: f"{r[key]:.1f}" if key in r else "-")  # noqa: E731
            print(f"{n:>9} {side:>5} {1e3 * med[side]:8.2f} {r['dispatches']:10.1f} {fmt('groups_created'):>10} "
                  f"{fmt('uniforms_created'):>12} {r['keys']:>9}  {r['module']}")
        if "peer" in med:
            print(f"  N={n}: host recording per frame {1e3 * med['peer']:.2f} -> {1e3 * med['ours']:.2f} ms "
                  f"({med['peer'] / med['ours']:.2f}x less); per round: "
                  + ", ".join(f"{p['host_s'] / o['host_s']:.2f}x" for p, o in zip(runs["peer"], runs["ours"])))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--no-oracle", action="store_true")
    ap.add_argument("--size", default=f"{WIDTH}x{HEIGHT}",
                    help="frame WIDTHxHEIGHT (default 1920x1080; the scene fills the same field of view)")
    ap.add_argument("--variants", nargs="+", choices=sorted(VARIANTS),
                    help="time these radix sort variants with the sorts in WGSL (first = the peer)")
    ap.add_argument("--rounds", type=int, default=1, help="alternating rounds of the variants (medians reported)")
    ap.add_argument("--gpu-times", action="store_true", help="device time per kernel of one frame (timestamp queries)")
    ap.add_argument("--host-recording", action="store_true",
                    help="only the host's recording time per frame (--repeat frames per process, --rounds rounds)")
    ap.add_argument("--peer", help="with --host-recording: a checkout whose r360gpu is measured alike (its .venv)")
    ap.add_argument("--host-child", nargs=3, metavar=("N", "SIZE", "FRAMES"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.host_child:
        n, size, count = args.host_child
        w, h = (int(v) for v in size.lower().split("x"))
        print(json.dumps(host_recording(int(n), w, h, int(count))))
        return 0
    width, height = (int(v) for v in args.size.lower().split("x"))
    if args.host_recording:
        bench_host_recording(args.sizes, (width, height), args.repeat, args.rounds, args.peer)
        return 0
    variants = tuple(args.variants) if args.variants else (None,)
    if args.variants:
        os.environ["R360GPU_SORT"] = "gpu"
    ctx = get_context()
    d = ctx.describe()
    print(f"adapter: {d['name']} ({d['backend']}, {d['adapter_type']}); CPU cores: {os.cpu_count()}")
    flops = peak_flops()
    pair_limit = flops / FLOPS_PER_PAIR
    print(f"CPU float32 peak (sgemm): {flops / 1e9:.1f} GFLOP/s -> physical limit ~{pair_limit / 1e9:.2f} G pairs/s "
          f"at {FLOPS_PER_PAIR} flop/pair")
    print()
    header = (f"{'N':>9} {'sort':>7} {'upload ms':>9} {'project':>8} {'sort':>8} {'raster':>8} {'sum':>8} "
              f"{'device ms':>9} {'+readback':>9} {'waits':>5} {'keys':>10} {'evaluated':>12} {'blended':>11} "
              f"{'Gpairs/s':>9} {'of limit':>8}")
    print(header)
    print("-" * len(header))
    results = []
    for n in args.sizes:
        per = bench_size(ctx, n, args.repeat, width, height, variants, args.rounds, args.gpu_times)
        for v, r in per.items():
            results.append(r)
            s = r["stages"]
            rate = r["evaluated"] / s["rasterize"]
            label = v or ("host" if ctx.kernel_backend("sort") == "cpu" else "wgsl")
            print(f"{n:>9} {label:>7} {1e3 * r['upload_s']:>9.0f} {1e3 * s['project']:>8.1f} {1e3 * s['sort']:>8.1f} "
                  f"{1e3 * s['rasterize']:>8.1f} {1e3 * sum(s.values()):>8.1f} {1e3 * r['device_s']:>9.1f} "
                  f"{1e3 * r['frame_s']:>9.1f} {r['frame_waits']:>5.0f} {r['keys']:>10} {r['evaluated']:>12} "
                  f"{r['blended']:>11} {rate / 1e9:>9.3f} {rate / pair_limit:>8.1%}")
        if len(per) == 2:
            (pv, peer), (ov, ours) = per.items()
            same = all(np.array_equal(getattr(peer["out"], k), getattr(ours["out"], k))
                       for k in ("rgb", "alpha", "depth", "median_depth"))
            print(f"  {ov} vs {pv} (peer), N={n}: sort stage {1e3 * peer['stages']['sort']:.1f} -> "
                  f"{1e3 * ours['stages']['sort']:.1f} ms ({peer['stages']['sort'] / ours['stages']['sort']:.2f}x), "
                  f"device frame {1e3 * peer['device_s']:.1f} -> {1e3 * ours['device_s']:.1f} ms "
                  f"({peer['device_s'] / ours['device_s']:.2f}x), frame with readback "
                  f"{1e3 * peer['frame_s']:.1f} -> {1e3 * ours['frame_s']:.1f} ms "
                  f"({peer['frame_s'] / ours['frame_s']:.2f}x); images bit-equal: {same}")
    for r in results:
        tag = f" ({r['variant']} sort)" if r["variant"] else ""
        print(f"  numpy read-back of the image, N={r['n']}{tag}: colour interleaved on the device "
              f"{1e3 * r['readback_s']:.1f} ms; on the host (peer: the previous way) {1e3 * r['readback_peer_s']:.1f} ms "
              f"({r['readback_peer_s'] / r['readback_s']:.2f}x); bit-equal: {r['readback_same']}")
    if args.gpu_times:
        print_kernel_times(results, "timestamp-query" in ctx.features)
    print()
    print(f"frame {width}x{height}; waits = host reads from the device per read-back frame "
          f"(device frames: {results[0]['device_waits']:.0f} before the image is complete)")
    for r in results:
        tag = f" ({r['variant']} sort)" if r["variant"] else ""
        print(f"frames/s at {r['n']} Gaussians {width}x{height}{tag}: {1 / r['device_s']:.2f} "
              f"(image on the device), {1 / r['frame_s']:.2f} (read back to numpy)")
        if r["n"] == 1_000_000 and (width, height) == (WIDTH, HEIGHT):
            ok = r["frame_s"] <= GOAL_1M_S
            print(f"goal: 1M Gaussians at 1080p in <= {GOAL_1M_S:.0f} s: {'MET' if ok else 'NOT MET'} "
                  f"({r['frame_s']:.2f} s per frame)")
    if not args.no_oracle:
        o = bench_oracle(ctx)
        print(f"numpy oracle, {o['n']} Gaussians at {o['size']}: oracle {1e3 * o['oracle_s']:.0f} ms, "
              f"GPU renderer {1e3 * o['gpu_s']:.0f} ms (x{o['oracle_s'] / o['gpu_s']:.1f} faster), "
              f"max RGB difference {o['max_rgb_err']:.2e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
