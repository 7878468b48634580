"""What starting the GPU context in a background thread could save `r360gpu score`, in one run.

    python bench/bench_startup.py [--views 100 --width 290 --height 220] [--repeat 5]

Creating the context (r360gpu.gpu.get_context) is importing wgpu, whose first
use parses its C header with cffi/pycparser (pure Python, holding the GIL),
then the native Vulkan instance, adapter and device.  A thread can only hide
the part that leaves the GIL free, and only behind work that does the same.

1. The context alone, and beside a busy pure-Python thread (as the imports
   before the first view are): how much slower it gets there (every C call
   gives the GIL up and may wait a switch interval to get it back).
2. `r360gpu score` on a generated public-layout folder (bench_vs_public.make_scene,
   precomputed masks), each run a fresh process, alternating: as it is
   (the peer), and with get_context started in a thread at process entry (the
   earliest possible start, so an upper bound for any placement).  Prints the
   median time to the first view's measure stage, the median total, and the ratio.
The load average is printed: on a busy machine the differences drown.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# A fresh process: the context created alone, or beside a thread counting in pure Python.
CONTEXT_ALONE = """
import json, threading, time
def spin(stop, out):
    n = 0
    while not stop.is_set():
        n += 1
    out.append(n)
def spin_rate(sec=0.3):
    stop, out = threading.Event(), []
    t = threading.Thread(target=spin, args=(stop, out)); t.start(); time.sleep(sec); stop.set(); t.join()
    return out[0] / sec
beside = {beside}
rate = spin_rate() if beside else None
stop, out = threading.Event(), []
t = threading.Thread(target=spin, args=(stop, out))
if beside:
    t.start()
t0 = time.perf_counter()
from r360gpu.gpu import get_context
ctx = get_context()
wall = time.perf_counter() - t0
stop.set()
if beside:
    t.join()
print(json.dumps({{"wall": wall, "spinner_s": out[0] / rate if beside else 0.0,
                  "adapter": ctx.adapter_info["adapter_type"]}}))
"""

# A fresh `r360gpu score`, timing the first view's measure stage; BACKGROUND starts the context first.
SCORE = """
import sys, threading, time
T0 = time.perf_counter()
if {background}:
    from r360gpu.gpu import get_context
    threading.Thread(target=get_context, daemon=True).start()
import r360gpu.pipeline.stages as stages
first = []
_measure = stages.measure
def measure(*a, **k):
    if not first:
        first.append(time.perf_counter() - T0)
    return _measure(*a, **k)
stages.measure = measure
from r360gpu.cli import main
rc = main(sys.argv[1:])
print("BENCH", first[0], time.perf_counter() - T0)
sys.exit(rc)
"""


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def run_json(code: str, env) -> dict:
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT)
    if p.returncode:
        sys.exit(f"context run failed:\n{p.stderr[-3000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def run_score(background: bool, scene: Path, out: Path, env) -> tuple[float, float]:
    shutil.rmtree(out, ignore_errors=True)
    args = ["score", str(scene), "--out", str(out), "--quiet", "--semantic-probe", f"png:{scene}/gsam2",
            "--structural-probe", f"sam-json:pre={scene}/masks,post={scene}/sam/after"]
    p = subprocess.run([sys.executable, "-c", SCORE.format(background=background), *args],
                       capture_output=True, text=True, env=env, cwd=ROOT)
    if p.returncode:
        sys.exit(f"score failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}")
    first, total = (float(x) for x in p.stdout.strip().splitlines()[-1].split()[1:])
    return first, total


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--views", type=int, default=100)
    ap.add_argument("--width", type=int, default=290)
    ap.add_argument("--height", type=int, default=220)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    sys.path.insert(0, str(HERE))
    from bench_vs_public import make_scene

    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    print(f"# GPU context creation off the critical path? CPU cores: {os.cpu_count()}; load average: {load()}")
    alone = [run_json(CONTEXT_ALONE.format(beside=False), env) for _ in range(args.repeat)]
    beside = [run_json(CONTEXT_ALONE.format(beside=True), env) for _ in range(args.repeat)]
    ctx_s = float(np.median([r["wall"] for r in alone]))
    print(f"context ({alone[0]['adapter']} adapter): {ctx_s:.3f} s alone; beside a busy Python thread "
          f"{np.median([r['wall'] for r in beside]):.3f} s (the thread did "
          f"{np.median([r['spinner_s'] for r in beside]):.3f} s of its solo work meanwhile)")

    tmp = Path(tempfile.mkdtemp(prefix="r360-startup-"))
    try:
        make_scene(tmp / "scene", args.views, args.height, args.width)
        runs: dict = {False: [], True: []}
        for k in range(args.repeat):
            for background in (False, True):
                runs[background].append(run_score(background, tmp / "scene", tmp / "out", env))
                first, total = runs[background][-1]
                print(f"run {k} {'background' if background else 'serial    '}: first measure at {first:.3f} s, "
                      f"total {total:.3f} s  (load {load()})")
        med = {b: np.median(np.array(r), axis=0) for b, r in runs.items()}
        print()
        print(f"| {args.views} views {args.width}x{args.height} | serial (peer) | context in a thread | ratio |")
        print("|---|---|---|---|")
        for i, what in enumerate(("first view measured", "total")):
            print(f"| {what} | {med[False][i]:.3f} s | {med[True][i]:.3f} s | {med[False][i] / med[True][i]:.2f}x |")
        print(f"load average after: {load()}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
