"""`r360gpu demo`, first run (nothing kept from before), against the 20 s goal and another source tree.

    python bench/bench_demo.py [--rounds 3] [--against PATH] [--processes N] [--orbit N] [--goal 20]

Each run is a fresh process, ``python -m r360gpu demo --out TMP --quiet`` in
a new folder, so the benchmark is generated and scored from nothing.  With
``--against`` (another checkout, e.g. a ``git worktree`` of an older commit)
the two trees are run alternately, round by round, so both see the same
machine load; the ratio of the medians is printed.  With ``--processes N``
this tree's demo with ``--processes N`` is run alternately with the plain
one the same way.  r360gpu's bytecode is compiled
before the first run (``common.bytecode_env``).  Wall time and the CPU
time of the process (user + system, both cores) are reported per run, with
the machine's load average before and after.  ``--orbit N`` runs every demo
with ``--orbit N`` (the 3D features' cost, e.g. of one tree against another).
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from common import bytecode_env  # noqa: E402


def run_demo(root: Path, out: Path, extra: list, env: dict) -> tuple[float, float]:
    """(wall s, CPU s) of one first run of the demo from source tree ``root``."""
    shutil.rmtree(out, ignore_errors=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    # run from the timed tree: `python -m` puts the working directory first on sys.path
    p = subprocess.run([sys.executable, "-m", "r360gpu", "demo", "--out", str(out), "--quiet", *extra], cwd=root,
                       capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        sys.exit(f"demo failed in {root} ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-4000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="runs of each tree (default 3)")
    ap.add_argument("--against", type=Path, default=None, help="another r360gpu source tree, run alternately")
    ap.add_argument("--processes", type=int, default=None,
                    help="also run this tree's demo with --processes N, alternately")
    ap.add_argument("--orbit", type=int, default=None, help="run every demo with --orbit N")
    ap.add_argument("--goal", type=float, default=20.0, help="wall-time goal in s (default 20)")
    args = ap.parse_args()
    common = [] if args.orbit is None else ["--orbit", str(args.orbit)]
    trees = {"this": (ROOT, common)}
    if args.against is not None:
        if not (args.against / "r360gpu" / "__init__.py").is_file():
            sys.exit(f"{args.against}: not an r360gpu source tree")
        trees["against"] = (args.against.resolve(), common)
    if args.processes is not None:
        trees["processes"] = (ROOT, ["--processes", str(args.processes), *common])
    env = bytecode_env({root / "r360gpu" for root, _ in trees.values()})
    print(f"# r360gpu demo, first run: {os.cpu_count()} CPU cores; load average before: "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for name, (root, extra) in trees.items():
        print(f"  {name}: {root} {' '.join(extra)}")
    times: dict = {name: [] for name in trees}
    tmp = Path(tempfile.mkdtemp(prefix="r360-bench-demo-"))
    try:
        for k in range(args.rounds):
            for name, (root, extra) in trees.items():
                wall, cpu = run_demo(root, tmp / name, extra, env)
                times[name].append(wall)
                print(f"round {k}: {name:8s} {wall:6.2f} s wall, {cpu:6.2f} s CPU", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    med = {name: statistics.median(t) for name, t in times.items()}
    for name, t in times.items():
        met = sum(x <= args.goal for x in t)
        print(f"{name}: median {med[name]:.2f} s (runs {min(t):.2f}-{max(t):.2f} s); "
              f"<= {args.goal:g} s in {met} of {len(t)} runs")
    for other in ("against", "processes"):
        if other in med:
            print(f"ratio ({other} / this): {med[other] / med['this']:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
