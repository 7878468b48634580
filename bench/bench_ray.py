"""Scoring on Ray vs the serial run: views/s with 1 and 2 local workers on the same input.

One synthetic scene is scored serially (in this process), then with
``executor="ray"`` on a local Ray instance of 1 and of 2 CPUs (one task per
CPU), then serially again.  Each run starts from an empty output folder.  Printed per run: Ray
start-up, the scoring wall time (driver load + probe fit + tasks + aggregate),
views/s, the ratio to serial, and whether the results document equals the
serial one (timing and creation time left out).

    python bench/bench_ray.py [--views 8] [--width 320] [--height 240] [--workers 1 2] [--no-pictures]

Needs the ``ray`` extra (pip install 'r360gpu[ray]').
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def comparable(doc: dict) -> dict:
    return {k: v for k, v in doc.items() if k not in ("timing", "created")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--scene", default="room", choices=["room", "garden"])
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--chunk", type=int, default=None, help="views per task (default: the executor's)")
    ap.add_argument("--no-pictures", action="store_true")
    args = ap.parse_args(argv)

    import ray

    from common import header
    from r360gpu.gpu import get_context
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.pipeline.distributed import RayExecutor, RayOptions
    from r360gpu.synthetic import generate_benchmark

    header("Scoring on Ray vs serial")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"input: 1 scene ({args.scene}), {args.views} views at {args.width}x{args.height}, 5 methods + 2 controls; "
          f"pictures {'off' if args.no_pictures else 'on'}; load average at start {load:.1f}; "
          f"LP_NUM_THREADS={os.environ.get('LP_NUM_THREADS', 'unset')}")
    ctx = get_context()
    opts = EvaluateOptions(n_boot=200, n_perm=100, pictures=not args.no_pictures)
    with tempfile.TemporaryDirectory(prefix="r360-bench-ray-") as tmp:
        tmp = Path(tmp)
        bundle = generate_benchmark(tmp / "bench", seed=0, n_views=args.views, width=args.width, height=args.height,
                                    scenes=(args.scene,), detail=0.5, ctx=ctx)[0]
        t = time.perf_counter()
        serial = evaluate(bundle, out=tmp / "serial", options=opts, ctx=ctx, progress=False)
        serial_s = time.perf_counter() - t
        rows = [("serial", 0.0, serial_s, serial["timing"], None, True)]
        for n in args.workers:
            t = time.perf_counter()
            ray.init(num_cpus=n, include_dashboard=False, object_store_memory=300 * 2**20,
                     logging_level="WARNING")
            start_s = time.perf_counter() - t
            ex = RayExecutor(RayOptions(chunk=args.chunk), log=lambda *a: None)
            try:
                t = time.perf_counter()
                res = evaluate(bundle, out=tmp / f"ray{n}", options=opts, ctx=ctx, progress=False, executor=ex)
                wall = time.perf_counter() - t
            finally:
                ray.shutdown()
            rows.append((f"ray, {n} worker{'s' if n > 1 else ''}", start_s, wall, res["timing"], ex.tasks,
                         comparable(res) == comparable(serial)))
        # the serial run again, last: the machine's load drifts, so the baseline is the mean of both
        t = time.perf_counter()
        again = evaluate(bundle, out=tmp / "serial2", options=opts, ctx=ctx, progress=False)
        rows.append(("serial (again, last)", 0.0, time.perf_counter() - t, again["timing"], None,
                     comparable(again) == comparable(serial)))
        serial_s = (serial_s + rows[-1][2]) / 2

    print()
    print(f"baseline: mean of the two serial runs, {serial_s:.1f} s")
    print("| run | Ray start s | scoring s | views/s | vs serial | tasks | fit s | results equal serial |")
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    for name, start_s, wall, timing, tasks, equal in rows:
        vps = args.views / wall
        fit = timing["stages_s"].get("fit probes", 0.0)
        print(f"| {name} | {start_s:.1f} | {wall:.1f} | {vps:.3f} | {serial_s / wall:.2f}x | "
              f"{'-' if tasks is None else tasks} | {fit:.1f} | {equal} |")
    print()
    s = rows[0][3]["stages_s"]
    print("serial stages (s): " + ", ".join(f"{k} {v:.1f}" for k, v in s.items()))
    for name, _, _, timing, _, _ in rows[1:-1]:
        st = timing["stages_s"]
        print(f"{name}: summed worker stages (s): "
              + ", ".join(f"{k} {v:.1f}" for k, v in st.items() if k not in ("load", "fit probes", "ray wait"))
              + f"; driver waited {st.get('ray wait', 0):.1f}")
    return 0 if all(r[5] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
