"""`r360gpu score` end to end against the public Remove360 evaluation scripts, on the same folder.

    python bench/bench_vs_public.py --public PATH [--views 20 --width 1200 --height 1000] [--repeat 1]
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

Timed, each as one fresh process, on fresh copies of the folder:
* peer: the public depth_diff + semantic + depth + SAM evaluation (one thread);
* r360gpu: ``r360gpu score FOLDER --out OUT`` with default options and the
  same precomputed masks (``--semantic-probe png:FOLDER/gsam2
  --structural-probe sam-json:pre=FOLDER/masks,post=FOLDER/sam/after``).
Prints both times, the ratio, and the machine's load average; then an input
floor: a fresh Python process that imports numpy and OpenCV, decodes every PNG
of the folder and makes one vectorised pass over every SAM JSON byte (the
least any Python evaluator of the folder does), with its decoding spread
over the cores, and the ratio to the public scripts such a floor would give;
then the same floor with r360gpu's GPU device opened (a fresh process timing
``get_context()``; its CPU time counted as if spread perfectly over the cores
beside the decoding), the least r360gpu as designed can take.
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

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


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
import sys, time
t0 = time.perf_counter()
from pathlib import Path
import cv2, numpy as np
t1 = time.perf_counter()
png = js = 0.0
for f in sorted(Path(sys.argv[1]).rglob("*")):
    if f.suffix == ".png":
        t = time.perf_counter(); cv2.imdecode(np.frombuffer(f.read_bytes(), np.uint8), cv2.IMREAD_UNCHANGED)
        png += time.perf_counter() - t
    elif f.suffix == ".json":
        t = time.perf_counter(); int(np.count_nonzero(np.frombuffer(f.read_bytes(), np.uint8) == 116))
        js += time.perf_counter() - t
print(t1 - t0, png, js)
"""


def input_floor(folder: Path, env) -> tuple[float, float, float, float]:
    """(wall of a fresh process, its import of numpy + cv2, PNG decoding, one byte pass over the
    SAM JSON), all single-threaded: what any Python evaluator of this folder must at least do
    (start, decode every PNG it reads, look at every byte of the JSON once)."""
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _FLOOR_CODE, str(folder)], capture_output=True, text=True, env=env,
                       check=True)
    wall = time.perf_counter() - t
    imports, png, js = (float(x) for x in p.stdout.split())
    return wall, imports, png, js


_DEVICE_CODE = """
import time
import cv2, numpy as np
from r360gpu.gpu import get_context
w, c = time.perf_counter(), time.process_time()
ctx = get_context()
print(time.perf_counter() - w, time.process_time() - c, ctx.adapter_info["adapter_type"])
"""


def device_open(env, cwd) -> tuple[float, float, str]:
    """(wall, CPU of every thread, adapter type) of opening r360gpu's GPU device in a fresh process
    that has numpy and cv2 imported already: importing wgpu's backend, the adapter, the device."""
    p = subprocess.run([sys.executable, "-c", _DEVICE_CODE], capture_output=True, text=True, env=env, cwd=cwd,
                       check=True)
    wall, cpu, kind = p.stdout.split()
    return float(wall), float(cpu), kind


def timed(cmd, env=None, cwd=None) -> tuple[float, str]:
    t = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd)
    dt = time.perf_counter() - t
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {' '.join(map(str, cmd))}\n{p.stdout[-2000:]}\n{p.stderr[-4000:]}")
    return dt, p.stdout


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--public", required=True, type=Path, help="anything_left checkout or bare git dir")
    ap.add_argument("--views", type=int, default=20)
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (the median is reported)")
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
        print(f"# r360gpu score vs the public Remove360 scripts: {args.views} views of {args.width}x{args.height}")
        print(f"generated in {time.perf_counter() - t:.1f} s; CPU cores: {os.cpu_count()}; "
              f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        env = {**os.environ, "PYTHONPATH": f"{args.r360_root.resolve()}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
        peer, ours = [], []
        for k in range(args.repeat):
            run = tmp / f"run{k}"
            shutil.rmtree(run, ignore_errors=True)
            shutil.copytree(scene, run / "peer")
            dt, out = timed([sys.executable, str(HERE / "run_public.py"), str(public), str(run / "peer")], env)
            peer.append(dt)
            peer_axes = out.strip().splitlines()[-1]
            s = run / "peer"
            cmd = [sys.executable, "-m", "r360gpu", "score", str(s), "--out", str(run / "r360"), "--quiet",
                   "--semantic-probe", f"png:{s}/gsam2",
                   "--structural-probe", f"sam-json:pre={s}/masks,post={s}/sam/after", *args.r360_args.split()]
            # run from the timed tree: `python -m` puts the working directory first on sys.path,
            # ahead of PYTHONPATH, so from another checkout it would import that one
            dt, _ = timed(cmd, env, cwd=args.r360_root.resolve())
            ours.append(dt)
            res = json.loads((run / "r360" / "results.json").read_text())
            ax = next(iter(res["scenes"].values()))["methods"]["after"]["axes"]
            print(f"run {k}: public {peer[-1]:.2f} s, r360gpu {ours[-1]:.2f} s  "
                  f"(stages {res['timing']['stages_s']})")
            print(f"  public axes {peer_axes}; r360gpu s_sem {ax['s_sem']:.3f} s_geo {ax['s_geo']:.3f} "
                  f"s_str {ax['s_str']:.3f}")
        p, o = float(np.median(peer)), float(np.median(ours))
        wall, imports, png, js = input_floor(scene, env)
        cores = os.cpu_count() or 1
        # the start (interpreter + imports) is serial; decoding and scanning could use every core
        floor = wall - png - js + (png + js) / cores
        print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        print(f"input floor: a process that imports numpy + cv2 ({imports:.2f} s), decodes every PNG "
              f"({png:.2f} s) and looks at every SAM JSON byte once ({js:.2f} s) takes {wall:.2f} s on one core, "
              f"{floor:.2f} s spread over {cores}; 10x the public scripts needs <= {p / 10:.2f} s")
        # r360gpu also opens its GPU device: CPU work (all of it on lavapipe), counted as if it ran
        # perfectly beside the decoding, so this floor is a lower bound for r360gpu as designed
        dev_wall, dev_cpu, kind = device_open(env, args.r360_root.resolve())
        dev_floor = wall - png - js + (png + js + dev_cpu) / cores
        print(f"GPU device ({kind} adapter): opening it takes {dev_wall:.2f} s, {dev_cpu:.2f} s of CPU; the input "
              f"floor with it, every CPU second spread over {cores} cores: {dev_floor:.2f} s")
        print()
        print("| workload | public scripts | r360gpu score | ratio | input floor | best ratio possible | "
              "floor with the GPU device | best ratio possible with it |")
        print("|---|---|---|---|---|---|---|---|")
        print(f"| {args.views} views {args.width}x{args.height} | {p:.2f} s | {o:.2f} s | {p / o:.2f}x | "
              f"{floor:.2f} s | {p / floor:.1f}x | {dev_floor:.2f} s | {p / dev_floor:.1f}x |")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
