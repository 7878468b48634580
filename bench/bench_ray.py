"""Scoring on Ray vs the serial run: views/s with 1 and 2 local workers on the same input.

One synthetic scene is scored serially (in this process) and with
``executor="ray"`` on a local Ray instance of 1 and of 2 CPUs (one task per
CPU), in interleaved rounds, each run into an empty output folder.  Printed
per configuration (median over rounds): Ray start-up, the scoring wall time
(driver load + probe fit + tasks + aggregate), views/s, the ratio to serial,
and whether every results document equals the first serial one (timing and
creation time left out); then the CPU cores the serial run already uses and
how many tasks were busy at once.

    python bench/bench_ray.py [--views 8] [--width 320] [--height 240] [--workers 1 2] [--rounds 2] [--no-pictures]

Needs the ``ray`` extra (pip install 'r360gpu[ray]').
"""
from __future__ import annotations

import argparse
import os
import statistics
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
    ap.add_argument("--rounds", type=int, default=2, help="interleaved rounds; the median is shown (default 2)")
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
    configs = [0, *args.workers]  # 0: serial
    runs = {n: [] for n in configs}  # n -> [(ray start s, scoring s, process CPU s, timing, tasks, equal)]
    with tempfile.TemporaryDirectory(prefix="r360-bench-ray-") as tmp:
        tmp = Path(tmp)
        bundle = generate_benchmark(tmp / "bench", seed=0, n_views=args.views, width=args.width, height=args.height,
                                    scenes=(args.scene,), detail=0.5, ctx=ctx)[0]
        serial = None
        # Rounds interleave the configurations, so a change of the machine's load hits them alike.
        for r in range(args.rounds):
            for n in configs:
                out = tmp / f"r{r}-{n}"
                start_s, ex = 0.0, None
                if n:
                    t = time.perf_counter()
                    ray.init(num_cpus=n, include_dashboard=False, object_store_memory=300 * 2**20,
                             logging_level="WARNING")
                    start_s = time.perf_counter() - t
                    ex = RayExecutor(RayOptions(chunk=args.chunk), log=lambda *a: None)
                try:
                    t, c = time.perf_counter(), time.process_time()
                    res = evaluate(bundle, out=out, options=opts, device=ctx, progress=False, executor=ex)
                    wall, cpu = time.perf_counter() - t, time.process_time() - c
                finally:
                    if n:
                        ray.shutdown()
                serial = serial or res
                runs[n].append((start_s, wall, cpu, res["timing"], ex.tasks if ex else None,
                                comparable(res) == comparable(serial)))

    def med(n, i):
        return statistics.median(x[i] for x in runs[n])

    base = med(0, 1)
    print()
    print(f"median of {args.rounds} interleaved rounds; views/s = {args.views} views / scoring wall time "
          "(driver load + probe fit + tasks + aggregate; Ray start-up apart)")
    print("| run | Ray start s | scoring s | views/s | vs serial | tasks | results equal serial |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for n in configs:
        name = "serial" if n == 0 else f"Ray, {n} worker{'s' if n > 1 else ''}"
        tasks = "-" if n == 0 else runs[n][0][4]
        equal = all(x[5] for x in runs[n])
        print(f"| {name} | {med(n, 0):.1f} | {med(n, 1):.1f} | {args.views / med(n, 1):.3f} | "
              f"{base / med(n, 1):.2f}x | {tasks} | {equal} |")
    print()
    st = runs[0][-1][3]["stages_s"]
    print(f"serial: this process used {med(0, 2) / med(0, 1):.2f} CPU cores on average (lavapipe threads "
          f"included); stages (s): " + ", ".join(f"{k} {v:.1f}" for k, v in st.items()))
    for n in args.workers:
        st = runs[n][-1][3]["stages_s"]
        work = sum(v for k, v in st.items() if k not in ("load", "fit probes", "ray wait"))
        print(f"Ray, {n} worker(s): task stages summed {work:.1f} s over {st.get('ray wait', 0):.1f} s of tasks "
              f"({work / max(st.get('ray wait', 1e-9), 1e-9):.2f} tasks busy at once); driver load + fit "
              f"{st.get('load', 0) + st.get('fit probes', 0):.1f} s")
    return 0 if all(x[5] for n in configs for x in runs[n]) else 1

if __name__ == "__main__":
    sys.exit(main())
