"""`r360gpu score` end to end against the public Remove360 evaluation scripts, on the same folder.

    python bench/bench_vs_public.py --public PATH [--views 20 --width 1200 --height 1000] [--repeat 3]
    python bench/bench_vs_public.py --public PATH --views 100 --width 290 --height 220

PATH: a checkout of github.com/simonakocour/anything_left (or its bare git
directory, as the search tool's ``fetch`` leaves it; HEAD is then extracted
to a temporary folder).  Its code is run from there (bench/run_public.py),
never copied into this repository.

The folder is generated in the public evaluation layout, with what its scripts
read: ``rgb/{before,after}`` and 8-bit ``depth/{before,after}`` PNGs,
``masks/<view>.png`` target masks, Grounded-SAM-2 PNG masks
``gsam2/{before,after}/mask/<view>.png`` (no file where nothing is detected,
as their converter leaves it), and SAM automatic-mask JSON as
``scripts/run_sam_on_rgb.py`` writes it (``json.dump`` of
``{"segmentation": bool_mask.tolist(), "area", "bbox"}`` records, 1-7 per
view) for the "GT" side in ``masks/<view>.json`` and the method in
``sam/after/<view>.json``.

Timed, each as one fresh process, in rounds (``--repeat``, default 3; medians reported), every round
running the four in turn, each round starting one later so that each meets the same machine load:
* input floor: one fresh Python process per core, all started together; process k of n imports
  numpy and OpenCV, decodes every n-th PNG of the folder (from the k-th, in sorted order) with
  ``cv2.imread(path, cv2.IMREAD_UNCHANGED)`` and reads every n-th JSON file's bytes once; the
  floor is the wall time from the launch to the last exit;
* r360gpu: ``r360gpu score FOLDER --out OUT --no-pictures`` and the same with default options,
  with the same precomputed masks (``--semantic-probe png:FOLDER/gsam2
  --structural-probe sam-json:pre=FOLDER/masks,post=FOLDER/sam/after``), on the generated folder
  itself (checked unchanged afterwards), into a fresh output folder;
* peer: the public depth_diff + semantic + depth + SAM evaluation (one thread), on a fresh copy
  of the folder (its scripts write into it).
Every timed process reads its bytecode from ``__pycache__``, compiled beforehand for r360gpu and
the public checkout (``common.bytecode_env``), as for any user after a first run.
Prints the machine's load average before, during and after, each run's time, and a table: the
floor, both r360gpu times with their ratio to the floor (the goals: <= 1.5x without
pictures, <= 2.5x with), and the public scripts' time with its ratio to r360gpu's default run; then the CPU-seconds of the floor and of both r360gpu runs, and
the least wall time that CPU would allow on the machine's cores, as a multiple of the floor.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from common import bytecode_env  # noqa: E402


def sam_json_text(masks: list[np.ndarray]) -> str:
    """What ``json.dump`` writes for run_sam_on_rgb.py's records (built row by row: ~50x faster)."""
    recs = []
    for m in masks:
        rows = np.where(m, "true", "false")
        seg = "[" + ", ".join("[" + ", ".join(r) + "]" for r in rows) + "]"
        ys, xs = np.nonzero(m)
        bbox = [int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1] if xs.size else [0, 0, 0, 0]
        recs.append('{"segmentation": ' + seg + f', "area": {int(m.sum())}, "bbox": {json.dumps(bbox)}' + "}")
    return "[" + ", ".join(recs) + "]"


def _check_sam_json_text() -> None:
    rng = np.random.default_rng(1)
    masks = [rng.uniform(size=(5, 7)) < 0.5 for _ in range(3)]
    recs = []
    for m in masks:
        ys, xs = np.nonzero(m)
        recs.append({"segmentation": m.tolist(), "area": int(m.sum()),
                     "bbox": [int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1]})
    if sam_json_text(masks) != json.dumps(recs):
        sys.exit("sam_json_text no longer writes what json.dump writes")


def _ellipse(h, w, cy, cx, ry, rx):
    yy, xx = np.ogrid[:h, :w]
    return ((yy - cy) / ry) ** 2 + ((xx - cx) / rx) ** 2 <= 1.0


def _png(path: Path, img) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), img)


def make_scene(root: Path, n_views: int, height: int, width: int, seed: int = 0) -> Path:
    """A public-layout scene folder (see the module docstring); one method whose removal
    leaves a residue in some views."""
    rng = np.random.default_rng(seed)
    h, w = height, width
    yy, xx = np.mgrid[:h, :w].astype(np.float32)
    for i in range(n_views):
        v = f"{i:05d}"
        cy, cx = rng.uniform(0.35, 0.65) * h, rng.uniform(0.35, 0.65) * w
        ry, rx = rng.uniform(0.1, 0.2) * h, rng.uniform(0.1, 0.2) * w
        target = _ellipse(h, w, cy, cx, ry, rx)
        residue = target & (rng.uniform() < 0.4) & _ellipse(h, w, cy + ry / 2, cx, ry / 2, rx / 2)
        base = (np.stack([xx / w, yy / h, 0.5 + 0.5 * np.sin(xx / 37 + yy / 53)], -1) * 200).astype(np.float32)
        before = base.copy()
        before[target] = [40, 60, 200]
        after = base.copy()
        after[residue] = [40, 60, 200]
        noise = rng.normal(0, 4, (h, w, 3)).astype(np.float32)
        _png(root / "rgb" / "before" / f"{v}.png", np.clip(before + noise, 0, 255).astype(np.uint8))
        _png(root / "rgb" / "after" / f"{v}.png", np.clip(after + noise, 0, 255).astype(np.uint8))
        plane = 120 + 100 * yy / h + rng.normal(0, 1.0, (h, w))
        d_before = np.where(target, plane - 60, plane)
        d_after = np.where(residue, plane - 60, plane)
        _png(root / "depth" / "before" / f"{v}.png", np.clip(d_before, 1, 255).astype(np.uint8))
        _png(root / "depth" / "after" / f"{v}.png", np.clip(d_after, 1, 255).astype(np.uint8))
        _png(root / "masks" / f"{v}.png", target.astype(np.uint8) * 255)
        shift = np.roll(target, (int(rng.integers(-5, 6)), int(rng.integers(-5, 6))), (0, 1))
        _png(root / "gsam2" / "before" / "mask" / f"{v}.png", shift.astype(np.uint8) * 255)
        if residue.any():
            _png(root / "gsam2" / "after" / "mask" / f"{v}.png", residue.astype(np.uint8) * 255)
        for folder, obj in ((root / "masks", target), (root / "sam" / "after", residue)):
            segs = [obj] if obj.any() else []
            for _ in range(int(rng.integers(1, 8)) - len(segs)):
                segs.append(_ellipse(h, w, rng.uniform(0, h), rng.uniform(0, w), rng.uniform(0.05, 0.3) * h,
                                     rng.uniform(0.05, 0.3) * w))
            folder.mkdir(parents=True, exist_ok=True)
            (folder / f"{v}.json").write_text(sam_json_text(segs))
    (root / "prompt.txt").write_text("object\n")
    return root


def public_checkout(path: Path, tmp: Path) -> Path:
    if (path / "remove360").is_dir():
        return path
    out = tmp / "anything_left"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    archive = subprocess.run(["git", "--git-dir", str(path), "archive", "HEAD"], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(out)], input=archive.stdout, check=True)
    return out


_FLOOR_CODE = """
import sys
from pathlib import Path

import cv2
import numpy as np

folder, k, n = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
files = sorted(folder.rglob("*"))
for f in [f for f in files if f.suffix == ".png"][k::n]:
    if cv2.imread(str(f), cv2.IMREAD_UNCHANGED) is None:
        sys.exit(f"cannot decode {f}")
for f in [f for f in files if f.suffix == ".json"][k::n]:
    f.read_bytes()
"""


def _children_cpu() -> float:
    """User + system seconds of this process's finished children so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def input_floor(folder: Path, env, processes: int) -> tuple[float, float]:
    """Wall seconds from launching ``processes`` fresh Python processes at once (one per core) to the
    last one's exit; process k of n imports numpy and OpenCV, decodes every n-th PNG of the folder from
    the k-th with ``cv2.imread(path, cv2.IMREAD_UNCHANGED)`` and reads every n-th JSON file's bytes once:
    the least any Python evaluator of the folder does (start, decode what it scores, see every byte).
    Returns (wall s, CPU s of all the processes)."""
    cpu = _children_cpu()
    t = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", _FLOOR_CODE, str(folder), str(k), str(processes)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE) for k in range(processes)]
    outs = [p.communicate() for p in procs]
    wall = time.perf_counter() - t
    for p, (_, err) in zip(procs, outs):
        if p.returncode != 0:
            sys.exit(f"input floor process failed ({p.returncode}): {err.decode()[-2000:]}")
    return wall, _children_cpu() - cpu


def timed(cmd, env=None, cwd=None) -> tuple[float, str, float]:
    """(wall s, stdout, CPU s of the process and its children) of one run of ``cmd``."""
    cpu = _children_cpu()
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(map(str, cmd))}\n{p.stdout[-2000:]}\n{p.stderr[-4000:]}")
    return dt, p.stdout, _children_cpu() - cpu


def _listing(folder: Path) -> list:
    """(path, size, mtime) of every file under ``folder``: r360gpu must leave its input as it found it."""
    return sorted((str(f), f.stat().st_size, f.stat().st_mtime_ns) for f in folder.rglob("*") if f.is_file())


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--public", required=True, type=Path, help="anything_left checkout or bare git dir")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3, help="rounds (each runs all four; medians are reported)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the generated folder and outputs here")
    ap.add_argument("--r360-args", default="", help="extra r360gpu score arguments (quoted)")
    ap.add_argument("--r360-root", type=Path, default=ROOT, help="r360gpu source tree to time (default: this one)")
    args = ap.parse_args()

    _check_sam_json_text()
    tmp = Path(tempfile.mkdtemp(prefix="r360-vs-public-")) if args.keep is None else args.keep.resolve()
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        public = public_checkout(args.public.resolve(), tmp)
        t = time.perf_counter()
        params = json.dumps([args.views, args.height, args.width, 0])
        scene = tmp / "scene"
        if not (scene / ".params").is_file() or (scene / ".params").read_text() != params:
            shutil.rmtree(scene, ignore_errors=True)
            make_scene(scene, args.views, args.height, args.width)
            (scene / ".params").write_text(params)
        cores = os.cpu_count() or 1
        print(f"# r360gpu score vs the public Remove360 scripts: {args.views} views of {args.width}x{args.height}")
        print(f"generated in {time.perf_counter() - t:.1f} s; CPU cores: {cores}; load average before: {_load()}")
        # bytecode compiled once beforehand, as a user's checkout and installed packages have it
        env = {**bytecode_env([args.r360_root.resolve() / "r360gpu", public]),
               "PYTHONPATH": f"{args.r360_root.resolve()}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
        listing = _listing(scene)
        times: dict[str, list[float]] = {"floor": [], "no-pictures": [], "default": [], "public": []}
        cpus: dict[str, list[float]] = {"floor": [], "no-pictures": [], "default": []}

        def r360(name: str, k: int, extra: list[str]) -> None:
            out = tmp / f"run{k}" / name
            shutil.rmtree(out, ignore_errors=True)
            cmd = [sys.executable, "-m", "r360gpu", "score", str(scene), "--out", str(out), "--quiet",
                   "--semantic-probe", f"png:{scene}/gsam2",
                   "--structural-probe", f"sam-json:pre={scene}/masks,post={scene}/sam/after", *extra,
                   *args.r360_args.split()]
            # run from the timed tree: `python -m` puts the working directory first on sys.path,
            # ahead of PYTHONPATH, so from another checkout it would import that one
            dt, _, cpu = timed(cmd, env, cwd=args.r360_root.resolve())
            times[name].append(dt)
            cpus[name].append(cpu)
            res = json.loads((out / "results.json").read_text())
            ax = next(iter(res["scenes"].values()))["methods"]["after"]["axes"]
            scored = res["timing"]["total_s"]  # opening the scene to its last view's plots
            print(f"  r360gpu {name}: {dt:.2f} s, {cpu:.2f} CPU-s (views scored in {scored:.2f} s; start-up, outputs and exit "
                  f"{dt - scored:.2f} s); s_sem {ax['s_sem']:.3f} s_geo {ax['s_geo']:.3f} s_str {ax['s_str']:.3f}; "
                  f"thread-seconds per stage {res['timing']['stages_s']}")

        def peer(k: int) -> None:
            copy = tmp / f"run{k}" / "peer"  # the public scripts write into the scene folder
            shutil.rmtree(copy, ignore_errors=True)
            shutil.copytree(scene, copy)
            dt, out, _ = timed([sys.executable, str(HERE / "run_public.py"), str(public), str(copy)], env)
            times["public"].append(dt)
            shutil.rmtree(copy, ignore_errors=True)
            print(f"  public scripts: {dt:.2f} s; axes {out.strip().splitlines()[-1]}")

        def floor(k: int) -> None:
            wall, cpu = input_floor(scene, env, cores)
            times["floor"].append(wall)
            cpus["floor"].append(cpu)
            print(f"  input floor: {wall:.2f} s, {cpu:.2f} CPU-s")

        steps = [floor, lambda k: r360("no-pictures", k, ["--no-pictures"]), lambda k: r360("default", k, []), peer]
        for k in range(args.repeat):
            print(f"round {k} (load average {_load()}):")
            # each round starts one step later, so that every kind of run meets the same load
            for step in steps[k % len(steps):] + steps[:k % len(steps)]:
                step(k)
            shutil.rmtree(tmp / f"run{k}", ignore_errors=True)
        if _listing(scene) != listing:
            sys.exit("r360gpu score changed its input folder")
        print(f"load average after: {_load()}")
        med = {name: float(np.median(v)) for name, v in times.items()}
        fl = med["floor"]
        print()
        print(f"medians of {args.repeat} round(s); input floor: {cores} fresh processes started together, each "
              f"importing numpy + cv2, decoding 1/{cores} of the PNGs (cv2.imread, IMREAD_UNCHANGED) and reading "
              f"1/{cores} of the JSON bytes, launch to last exit")
        print("| workload | input floor | r360gpu --no-pictures | / floor (goal <= 1.5) | r360gpu default | "
              "/ floor (goal <= 2.5) | public scripts | public / r360gpu default |")
        print("|---|---|---|---|---|---|---|---|")
        print(f"| {args.views} views {args.width}x{args.height} | {fl:.2f} s | {med['no-pictures']:.2f} s | "
              f"{med['no-pictures'] / fl:.2f}x | {med['default']:.2f} s | {med['default'] / fl:.2f}x | "
              f"{med['public']:.2f} s | {med['public'] / med['default']:.2f}x |")
        cpu = {name: float(np.median(v)) for name, v in cpus.items()}
        print()
        print(f"CPU-seconds (medians; the floor's {cores} processes summed), and the least wall time that CPU "
              f"allows on {cores} cores, as a multiple of the floor:")
        print("| workload | floor | r360gpu --no-pictures | least wall / floor | r360gpu default | least wall / floor |")
        print("|---|---|---|---|---|---|")
        print(f"| {args.views} views {args.width}x{args.height} | {fl:.2f} s, {cpu['floor']:.2f} CPU-s | "
              f"{cpu['no-pictures']:.2f} CPU-s | {cpu['no-pictures'] / cores / fl:.2f}x | "
              f"{cpu['default']:.2f} CPU-s | {cpu['default'] / cores / fl:.2f}x |")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
