"""One run of r360gpu's checks and benchmarks on a machine with a GPU, in one table, within 8 minutes.

    python bench/device_suite.py [--public PATH] [--sam-onnx ENCODER DECODER] [--sam-src DIR --samexporter-src DIR]
        [--grounded DINO TOKENIZER SAM_ENCODER SAM_DECODER] [--budget 480] [--small]

Steps, each a fresh process with its share of the time left (a step that
runs out is stopped and marked so; the next one still runs):

1. ``r360gpu doctor``: the adapter, and every GPU kernel against its numpy
   oracle (pass / fail);
2. the renderer at 1M Gaussians, 1920x1080 (bench/bench_render.py): frames/s,
   goal >= 100;
2b. the WGSL radix sort alone (bench/bench_render_sort.py ``--no-frames``): 1M
   (u32, u32) pairs by 32 bits in keys/s of wall and of device time, beside
   wgpu_sort's published 1M pairs in 317 us (RTX A5000), and the renderer's
   two exact sorts of a 1M-Gaussian 1080p frame against one packed-key sort;
2c. the renderer's host recording per frame (bench/bench_render.py
   ``--host-recording``): main-thread CPU ms per device frame outside the waits;
3. ``r360gpu score`` against the public Remove360 scripts
   (bench/bench_vs_public.py, 20 views of 1200x1000): both times and the
   ratio; needs ``--public`` (a checkout of simonakocour/anything_left, or
   its bare git directory), else skipped;
4. the structural probe (bench/bench_amg.py ``--onnx``): r360gpu's SAM
   automatic masks, 32x32 points on a 640x480 image, on onnxruntime's GPU
   provider (``--device auto``: CUDA or WebGPU when the installed
   onnxruntime has one, else its CPU provider, said in the table); needs ``--sam-onnx`` (e.g. the random-weight ViT-B
   exports bench/parity_sam.py writes), else the tiny stand-in graphs of
   tests/onnx_graphs.py (they check the path, not the speed; marked so);
4b. our SAM automatic masks on the GPU provider against segment-anything's
   official ``SamAutomaticMaskGenerator`` on CUDA torch, on the same GPU
   (bench/bench_amg.py ``--torch-device cuda --probe-device auto --warmup``):
   SAM ViT-B with random weights, 32x32 points, 640x480, per-image times,
   the ratio (goal >= 3x) and the mask sets by Hungarian matching (count,
   pixel-identical pairs, least IoU); needs torch with CUDA and the
   segment-anything and samexporter sources (``--sam-src``,
   ``--samexporter-src``, or the installed packages), else "not available"
   with what is missing.  ``--sam-work DIR`` keeps the ONNX exports (the
   encoder's export takes minutes) for the next run;
4c. the grounded probe (bench/bench_grounded.py) on the GPU provider:
   ``--grounded`` files, else the stand-in graphs (the path: which
   providers start, the masks that come back);
5. ``r360gpu demo`` from nothing (bench/bench_demo.py's run) with
   ``R360GPU_HOST_THREADS=2`` (the count a 2-core machine uses), then with
   the host threads scaled to the machine's cores, then with ``--processes auto``
   (one worker process per two cores): wall times, goal < 5 s;
6. target lifting and target-mask rendering against a plain render
   (bench/bench_lift.py) at 1M Gaussians, 24 views, 1920x1080: both ratios,
   goal <= 1.5 each.

``--small`` shrinks every workload (100k Gaussians at 480x270, 4 views of
160x120, 8x8 points on 320x240, a 4-view 160x120 demo, lifting 100k
Gaussians in 4 views of 480x270) so the suite runs on
a CPU adapter (lavapipe) in a few minutes: that checks the suite, not the GPU.
The table (Markdown) is printed last, with the adapter, the date and the
load average; ``--out FILE`` also writes it there with every step's output.
"""
from __future__ import annotations

import argparse
import datetime
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--public", type=Path, default=None, help="anything_left checkout or bare git dir (step 3)")
    ap.add_argument("--sam-onnx", nargs=2, type=Path, default=None, metavar=("ENCODER", "DECODER"),
                    help="a SAM ONNX pair for the probe step (step 4)")
    ap.add_argument("--sam-src", type=Path, default=None, help="folder holding segment_anything (step 4b)")
    ap.add_argument("--samexporter-src", type=Path, default=None, help="folder holding samexporter (step 4b)")
    ap.add_argument("--sam-work", type=Path, default=None,
                    help="where step 4b writes (and reuses) its ONNX exports (default: a temporary folder)")
    ap.add_argument("--grounded", nargs=4, type=Path, default=None,
                    metavar=("DINO", "TOKENIZER", "SAM_ENCODER", "SAM_DECODER"), help="grounded probe files (4c)")
    ap.add_argument("--budget", type=float, default=480.0, help="seconds for the whole suite (default 480)")
    ap.add_argument("--small", action="store_true", help="small workloads: checks the suite on a CPU adapter")
    ap.add_argument("--adapter", default=None, help="r360gpu adapter choice passed to every step")
    ap.add_argument("--out", type=Path, default=None, help="also write the table and each step's output here")
    return ap.parse_args(argv)


class Step:
    """One command of the suite: what it printed, how long it took, the figure the table shows."""

    def __init__(self, name: str, argv: list[str] | None, share: float, why_skipped: str = ""):
        self.name, self.argv, self.share, self.why_skipped = name, argv, share, why_skipped
        self.status, self.wall, self.output, self.figure, self.goal = "skipped", 0.0, "", why_skipped, ""
        self.env: dict = {}  # variables this step sets on top of the suite's

    def run(self, env: dict, limit: float) -> None:
        t = time.perf_counter()
        try:
            p = subprocess.run(self.argv, cwd=ROOT, env={**env, **self.env}, capture_output=True, text=True,
                               timeout=max(limit, 1.0))
            self.output = p.stdout + p.stderr
            self.status = "ok" if p.returncode == 0 else f"exit {p.returncode}"
        except subprocess.TimeoutExpired as exc:
            out = exc.stdout or b""
            self.output = out.decode(errors="replace") if isinstance(out, bytes) else out
            self.status = f"stopped at {limit:.0f} s"
        self.wall = time.perf_counter() - t


def last(pattern: str, text: str):
    found = re.findall(pattern, text)
    return found[-1] if found else None


#: wgpu_sort's published figure: 1M (key, value) pairs sorted in this many microseconds on an RTX A5000.
WGPU_SORT_1M_US = 317


def describe(step: Step, small: bool, renders: int) -> None:
    """Fill the table's figure and goal columns from what the step printed."""
    out = step.output
    if step.name == "doctor":
        step.figure = last(r"adapter:\s+(.+)", out) or ""
        failed = last(r"(\d+) check\(s\) FAILED", out)
        step.figure += f"; {failed} check(s) FAILED" if failed else ("; all checks passed" if "all checks passed" in out
                                                                   else "")
    elif step.name == "render":
        fps = last(rf"frames/s at {renders} Gaussians \S+: ([\d.]+)", out)
        step.figure = f"{fps} frames/s (image on the device)" if fps else ""
        step.goal = ">= 100 frames/s at 1M, 1080p" + (" (not this size)" if small else "")
        if fps and not small:
            step.goal += " MET" if float(fps) >= 100 else " NOT MET"
    elif step.name == "render sort":
        rates = re.findall(r"^ *(serial|blocks) +(\S+) pairs +\d+ +32 +[\d.]+ +([\d.]+) +(\S+) +(\S+) +True$", out, re.M)
        packed = dict(re.findall(r"^  (serial|blocks): the renderer's exact sorts .*? ms \(([\d.]+)x\)", out, re.M))
        step.figure = "; ".join(
            f"{v}: {n} pairs {wall} Mkeys/s wall" + (f", {dev} Mkeys/s device" if dev != "-" else "")
            + (f" (packed-key sort of the frame's keys {packed[v]}x the exact pair's time)" if v in packed else "")
            for v, n, wall, _, dev in rates)
        step.goal = f"wgpu_sort: 1M pairs in {WGPU_SORT_1M_US} us on an RTX A5000 ({1e6 / WGPU_SORT_1M_US:.0f} Mkeys/s)"
    elif step.name == "render recording":
        host = last(r"(?m)^ *\d+ +ours +([\d.]+) +([\d.]+)", out)
        step.figure = f"{host[0]} ms host recording per frame ({host[1]} passes)" if host else ""
    elif step.name == "vs public":
        row = last(r"\| \d+ views [^|]+\| ([\d.]+) s \| ([\d.]+) s \| ([\d.]+)x \| ([\d.]+) s \| ([\d.]+)x "
                   r"\| ([\d.]+) s \| ([\d.]+)x", out)
        step.figure = (f"public {row[5]} s, r360gpu {row[3]} s, {row[6]}x; input floor {row[0]} s: "
                       f"r360gpu {row[4]}x it ({row[2]}x without pictures)" if row else "")
    elif step.name == "probe":
        line = last(r"(\S+ on \S+) \(batched decoder: (\w+)\)", out)
        per = last(r"([\d.]+) s per image", out)
        step.figure = (f"{per} s per image ({line[0]}, batched: {line[1]})" if line and per else "")
    elif step.name == "probe vs official":
        runs = dict(re.findall(r"^  (official|after)\s*: +([\d.]+) s wall", out, re.M))
        ratio = last(r"official/after: wall ([\d.]+)x", out)
        sets = last(r"official vs after: (\d+) / (\d+) masks, (\d+) pixel-identical pairs, min IoU ([\d.na]+)", out)
        step.figure = (f"official {runs.get('official')} s, r360gpu {runs.get('after')} s per image, {ratio}x; "
                       f"masks {sets[0]} / {sets[1]}, {sets[2]} pixel-identical, least IoU {sets[3]}"
                       if ratio and sets else "")
        step.goal = ">= 3x, equal mask sets" + (" (not this size)" if small else (
            " MET" if ratio and sets and float(ratio) >= 3 and sets[0] == sets[1] and sets[3] != "nan"
            and float(sets[3]) >= 0.99 else " NOT MET"))
    elif step.name == "grounded":
        per = last(r"([\d.]+) s per image", out)
        where = last(r"(GroundingDINO on \S+, SAM on \S+);", out)
        found = last(r"(\d+) instance\(s\)", out)
        step.figure = f"{per} s per image ({where}; {found} instance(s))" if per and where else ""
    elif step.name.startswith("demo"):
        secs = last(r"demo wall ([\d.]+) s", out)
        step.figure = f"{secs} s" if secs else ""
        step.goal = "< 5 s" + (" (not this size)" if small else (" MET" if secs and float(secs) < 5 else " NOT MET"))
    elif step.name == "lift":
        lift = last(r"ratio lift/plain ([\d.]+)", out)
        mask = last(r"ratio mask/plain ([\d.]+)", out)
        plain = last(r"plain render\s+[\d.]+ s\s+\(([\d.]+) ms/view\)", out)
        step.figure = f"plain {plain} ms/view; lift/plain {lift}, mask/plain {mask}" if lift and mask else ""
        step.goal = "<= 1.5 each" + (" (not this size)" if small else (
            " MET" if lift and mask and max(float(lift), float(mask)) <= 1.5 else " NOT MET"))


def stand_in_pair(folder: Path) -> tuple[Path, Path]:
    """The tiny SAM stand-ins of tests/onnx_graphs.py (need the onnx package)."""
    sys.path.insert(0, str(ROOT / "tests"))
    import onnx_graphs

    enc = onnx_graphs.sam_encoder_nchw(folder / "standin.encoder.onnx")
    dec = onnx_graphs.sam_decoder(
        folder / "standin.decoder.onnx", iou=[0.99, 0.95, 0.92, 0.93], radius=[80, 160, 168, 240],
        slope=[1.0, 1.0, 1.0, 1e-5],
    )
    return enc, dec


DEMO_SCRIPT = (
    "import subprocess, sys, time; t = time.perf_counter(); "
    "p = subprocess.run([sys.executable, '-m', 'r360gpu', 'demo', '--out', sys.argv[1], '--quiet'] + sys.argv[2:]); "
    "print(f'demo wall {time.perf_counter() - t:.2f} s'); sys.exit(p.returncode)"
)


#: Prints what step 4b needs that this machine has: CUDA torch (the GPU's name) and the folders
#: holding segment_anything and samexporter (given, or where they are installed).
NEEDS_SCRIPT = (
    "import importlib.util, json, sys; out = {}\n"
    "try:\n import torch; out['cuda'] = torch.cuda.get_device_name() if torch.cuda.is_available() else None\n"
    "except ImportError: out['cuda'] = None\n"
    "for name, given in (('segment_anything', sys.argv[1]), ('samexporter', sys.argv[2])):\n"
    " if given: sys.path.insert(0, given)\n"
    " spec = importlib.util.find_spec(name)\n"
    " out[name] = given or (str(__import__('pathlib').Path(spec.origin).parent.parent) if spec else None)\n"
    "print(json.dumps(out))"
)


def official_step(args, work: Path) -> Step:
    """Step 4b, or why it cannot run here ("not available: ...")."""
    import json

    py = sys.executable
    p = subprocess.run([py, "-c", NEEDS_SCRIPT, str(args.sam_src or ""), str(args.samexporter_src or "")],
                       capture_output=True, text=True, timeout=120)
    try:
        have = json.loads(p.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        have = {}
    missing = [what for what, ok in (("torch with CUDA", have.get("cuda")),
                                     ("segment-anything (--sam-src)", have.get("segment_anything")),
                                     ("samexporter (--samexporter-src)", have.get("samexporter"))) if not ok]
    if missing:
        return Step("probe vs official", None, 0.3, f"not available: no {', no '.join(missing)}")
    size = ["--points-per-side", "8", "--size", "320x240"] if args.small else ["--points-per-side", "32"]
    sam_work = args.sam_work or work / "sam"
    return Step("probe vs official", [py, str(HERE / "bench_amg.py"), "--sam-src", have["segment_anything"],
                                      "--samexporter-src", have["samexporter"], "--work", str(sam_work),
                                      *(["--reuse-exports"] if args.sam_work else []), "--runs", "official,after",
                                      "--torch-device", "cuda", "--probe-device", "auto", "--warmup", *size], 0.3)


def build_steps(args, work: Path) -> list[Step]:
    py = sys.executable
    adapter = ["--adapter", args.adapter] if args.adapter else []
    small = args.small
    renders = 100_000 if small else 1_000_000
    steps = [Step("doctor", [py, "-m", "r360gpu", "doctor", *adapter], 0.15)]
    steps.append(Step("render", [py, str(HERE / "bench_render.py"), "--sizes", str(renders), "--repeat", "3",
                                 "--no-oracle"] + (["--size", "480x270"] if small else []), 0.2))
    frame = ["480", "270"] if small else ["1920", "1080"]
    steps.append(Step("render sort", [py, str(HERE / "bench_render_sort.py"), "--no-frames", "--sizes", str(renders),
                                      "--width", frame[0], "--height", frame[1], "--sort-reps", "3",
                                      "--pairs", "100000" if small else "1000000"], 0.05))
    steps.append(Step("render recording", [py, str(HERE / "bench_render.py"), "--host-recording", "--sizes",
                                           str(renders), "--size", "x".join(frame), "--rounds", "1",
                                           "--repeat", "5" if small else "20"], 0.05))
    if args.public is None:
        steps.append(Step("vs public", None, 0.3, "no --public checkout given"))
    else:
        size = ["--views", "4", "--width", "160", "--height", "120"] if small else []
        steps.append(Step("vs public", [py, str(HERE / "bench_vs_public.py"), "--public", str(args.public), "--repeat", "1",
                                     *size],
                          0.3))
    pair, label, why = args.sam_onnx, "", ""
    if pair is None:
        try:
            pair, label = stand_in_pair(work), "stand-in graphs (path check, not speed)"
        except ImportError as exc:
            # The reason goes in the table: on the first H100 run "onnx" was installed and still failed.
            pair, why = None, f"no --sam-onnx pair, and the stand-in graphs could not be built ({exc})".replace("|", "/")
    if pair is None:
        steps.append(Step("probe", None, 0.2, why))
    else:
        size = ["--points-per-side", "8", "--size", "320x240"] if small else []
        step = Step("probe", [py, str(HERE / "bench_amg.py"), "--onnx", str(pair[0]), str(pair[1]),
                              "--device", "auto", *size], 0.2)
        step.goal = label
        steps.append(step)
    steps.append(official_step(args, work))
    grounded = ["--grounded", *map(str, args.grounded)] if args.grounded else ["--stand-in"]
    step = Step("grounded", [py, str(HERE / "bench_grounded.py"), *grounded, "--device", "auto",
                             *(["--size", "320x240"] if small else [])], 0.05)
    step.goal = "" if args.grounded else "stand-in graphs (path check, not speed)"
    steps.append(step)
    demo_size = ["--n-views", "4", "--width", "160", "--height", "120"] if small else []
    # The 2-thread run first: a first run pays the cold file cache, which must not favour the default.
    two = Step("demo, 2 host threads", [py, "-c", DEMO_SCRIPT, str(work / "demo2"), *adapter, *demo_size], 0.15)
    two.env = {"R360GPU_HOST_THREADS": "2"}
    steps.append(two)
    steps.append(Step("demo", [py, "-c", DEMO_SCRIPT, str(work / "demo"), *adapter, *demo_size], 0.15))
    steps.append(Step("demo, --processes auto", [py, "-c", DEMO_SCRIPT, str(work / "demop"), *adapter, *demo_size,
                                                 "--processes", "auto"], 0.15))
    lift_size = (["--n", "100000", "--views", "4", "--width", "480", "--height", "270"] if small
                 else ["--n", "1000000", "--views", "24", "--width", "1920", "--height", "1080"])
    steps.append(Step("lift", [py, str(HERE / "bench_lift.py"), *lift_size, "--repeat", "1"], 0.15))
    return steps


def main(argv=None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    if args.adapter:
        env["R360GPU_ADAPTER"] = args.adapter
    load_before = os.getloadavg()
    work = Path(tempfile.mkdtemp(prefix="r360-suite-"))
    try:
        steps = build_steps(args, work)
        shares_left = sum(s.share for s in steps if s.argv)
        for step in steps:
            if not step.argv:
                continue
            left = args.budget - (time.perf_counter() - started)
            # Each step may use its share of what is left, and what earlier steps did not use.
            limit = left * step.share / shares_left if shares_left > 0 else left
            shares_left -= step.share
            if left < 5:
                step.status, step.figure = "skipped", "suite budget spent"
                continue
            print(f"[{time.perf_counter() - started:5.0f} s] {step.name} (up to {limit:.0f} s) ...", flush=True)
            step.run(env, limit)
            describe(step, args.small, 100_000 if args.small else 1_000_000)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    total = time.perf_counter() - started
    adapter = next((s.figure.split(";")[0] for s in steps if s.name == "doctor" and s.figure), "unknown adapter")
    lines = [
        f"## r360gpu device suite{' (--small)' if args.small else ''}: {adapter}",
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; {os.cpu_count()} CPU cores; "
        f"load average {load_before[0]:.1f} before, {os.getloadavg()[0]:.1f} after; "
        f"{total:.0f} s of a {args.budget:.0f} s budget",
        "",
        "| step | status | wall s | result | goal |",
        "|---|---|---|---|---|",
    ]
    for s in steps:
        lines.append(f"| {s.name} | {s.status} | {s.wall:.1f} | {s.figure} | {s.goal} |")
    table = "\n".join(lines)
    print()
    print(table)
    if args.out is not None:
        logs = "\n\n".join(f"### {s.name} ({s.status})\n```\n{s.output.strip()[-6000:]}\n```" for s in steps if s.argv)
        args.out.write_text(table + "\n\n" + logs + "\n")
    ran = [s for s in steps if s.argv]
    return 0 if ran and all(s.status == "ok" for s in ran) else 1


if __name__ == "__main__":
    raise SystemExit(main())
