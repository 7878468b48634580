"""Probe stage: r360gpu's SAM automatic mask generator against segment-anything's, on CPU.

Builds SAM ViT-B with random weights (fixed seed) and exports it to ONNX as
bench/parity_sam.py does (samexporter's encoder; segment-anything's
``SamOnnxModel`` decoder), twice for the decoder: with the prompt batch fixed
at 1 (samexporter's export, what most users have) and with it dynamic.  On the
same 640 x 480 image and the same parameters it times, per image:

* official: ``SamAutomaticMaskGenerator.generate`` on CPU torch (``--torch-device
  cuda``: on CUDA torch, for the GPU comparison of bench/device_suite.py);
* r360gpu, run "before": the plain path (the batch-1 export, one decoder run
  per prompt computing every decoder output), kept as the yardstick of the rewrites;
* r360gpu, run "after": the batched export, the decoder cut to the outputs the
  generator reads and its prompt-independent work run once per batch
  (``SamModels``), ``points_per_batch`` prompts per run;
* r360gpu unhoisted (only when asked for in ``--runs``): "after" without the
  second rewrite (``SamModels(..., hoist=False)``);

each with its image encoder run from scratch.  r360gpu's runs use onnxruntime's
provider for ``--probe-device`` (default cpu; ``auto``: the GPU one when installed,
r360gpu.probes.providers); ``--warmup`` runs each generator once untimed first (a GPU's
first run pays its kernels' compilation and the allocator's growth).

With ``--model sam2.1`` the same for SAM 2.1 Hiera-Tiny (random weights, built and
exported as bench/parity_sam2.py does: samexporter's ``export_sam2.py`` graphs, whose
decoder already takes a batch of prompts): official ``SAM2AutomaticMaskGenerator``
against r360gpu's generator on the exported pair ("after"; there is no "before"),
with parity_sam2's generator parameters; the run "algorithm" is r360gpu's generator
driven by the official torch predictor (parity_sam2's ``TorchSam2Models``), which
separates the algorithm from the export's float32 differences.

Mask sets are compared by Hungarian matching on IoU (counts, pixel-identical pairs, min IoU).  Then
the projected wall time of the paper's benchmark (11 scenes x 6 methods x
100 views; the structural probe on each post rendering and on each reference
rendering) from the per-image times, and the encoder time that a second probe
on the same SAM model saves per view (one encoding shared, see
``r360gpu.probes.onnx_models.EMBEDDINGS``).

Times are wall seconds and process CPU seconds (all threads): this machine is
shared, and the CPU figure moves less with the load (printed before and after).

    python bench/bench_amg.py --sam-src /tmp/sam-src --samexporter-src /tmp/samexporter-src \\
        [--work /tmp/probes-parity] [--points-per-side 32] [--runs official,before,after]
    python bench/bench_amg.py --model sam2.1 --gsam2-src /tmp/gsam2-src --samexporter-src /tmp/samexporter-src \\
        [--points-per-side 32] [--runs official,after]

Needs what bench/parity_sam.py needs (torch, onnx, onnxruntime, opencv, scipy
and the fetched sources, never committed).

Without torch, r360gpu's generator alone on any SAM ONNX pair and
onnxruntime device (what bench/device_suite.py runs on a GPU machine):

    python bench/bench_amg.py --onnx ENCODER DECODER [--device auto] [--points-per-side 32] [--repeat 2]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import parity_sam as P  # noqa: E402  (model building, exports, the official generator, matching)

#: The paper's benchmark: scenes x methods x views; per view the structural probe sees the
#: method's post rendering and the scene's reference rendering.
SCENES, METHODS, VIEWS = 11, 6, 100


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", choices=("sam", "sam2.1"), default="sam",
                    help="sam: SAM ViT-B (default); sam2.1: SAM 2.1 Hiera-Tiny")
    ap.add_argument("--sam-src", help="folder holding the fetched segment_anything package (--model sam)")
    ap.add_argument("--gsam2-src", help="folder holding Grounded-SAM-2's sam2 package with configs (--model sam2.1)")
    P.add_model_args(ap)
    ap.set_defaults(points_per_side=32)
    ap.add_argument("--points-per-batch", type=int, default=64)
    ap.add_argument("--size", default="640x480", help="image WIDTHxHEIGHT")
    ap.add_argument("--runs", default="official,before,after",
                    help="which generators to time, in this order (comma-separated)")
    ap.add_argument("--reuse-exports", action="store_true", help="keep ONNX files already in --work (same seed)")
    ap.add_argument("--torch-device", default="cpu", help="torch device of the official generator (cpu, cuda)")
    ap.add_argument("--probe-device", default="cpu", help="onnxruntime device of r360gpu's runs (cpu, cuda, webgpu, "
                                                          "auto, ...)")
    ap.add_argument("--warmup", action="store_true", help="run each generator once, untimed, before its timed run")
    args = ap.parse_args()
    src = {"sam": ("--sam-src", args.sam_src), "sam2.1": ("--gsam2-src", args.gsam2_src)}[args.model]
    if not src[1]:
        ap.error(f"--model {args.model} needs {src[0]}")
    runs = args.runs.split(",")
    if args.model == "sam2.1" and "before" in runs:
        ap.error("--model sam2.1: no 'before' run (samexporter's SAM 2 decoder already takes a prompt batch)")
    if args.model == "sam" and "algorithm" in runs:
        ap.error("--model sam: no 'algorithm' run (bench/parity_sam.py checks the algorithm on the torch model)")
    return args


def scene(rng, width: int, height: int) -> np.ndarray:
    """A synthetic RGB scene: coloured shapes on a gradient with noise (as bench/parity_sam.py's images)."""
    import cv2

    yy, xx = np.mgrid[0:height, 0:width]
    img = np.stack([xx * 200 / width, yy * 200 / height, np.full((height, width), 90.0)], -1).astype(np.uint8).copy()
    for _ in range(10):
        c = tuple(int(v) for v in rng.integers(0, 256, 3))
        x, y = int(rng.integers(0, width)), int(rng.integers(0, height))
        if rng.random() < 0.5:
            cv2.circle(img, (x, y), int(rng.integers(15, 90)), c, -1)
        else:
            cv2.rectangle(img, (x, y), (x + int(rng.integers(20, 150)), y + int(rng.integers(20, 150))), c, -1)
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


class BeforeDecoder:
    """The plain decoder path (run "before"): the whole graph, every output requested."""

    def __init__(self, path: Path):
        from r360gpu.probes.onnx_models import OnnxModel

        self.model = OnnxModel(path, "cpu", "SAM prompt decoder")
        self.path, self.inputs, self.outputs = self.model.path, self.model.inputs, self.model.outputs

    def run(self, feeds, outputs=None):
        return self.model.run(feeds, None)


def load_models(enc: Path, dec: Path, before: bool, hoist: bool = True, device: str = "cpu"):
    from r360gpu.probes.onnx_models import SamModels

    models = SamModels(enc, dec, device=device, hoist=hoist)
    if before:
        models.decoder = BeforeDecoder(dec)
    return models


def timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def load() -> str:
    return "load %.1f %.1f %.1f" % os.getloadavg()


def hours(seconds: float) -> str:
    return f"{seconds / 3600:.0f} h" if seconds >= 36000 else f"{seconds / 3600:.1f} h"


def onnx_only(argv) -> int:
    """r360gpu's generator alone on a given ONNX pair: per-image wall time, provider, mask count."""
    import dataclasses

    ap = argparse.ArgumentParser(description="r360gpu's SAM automatic masks on an ONNX pair")
    ap.add_argument("--onnx", nargs=2, required=True, metavar=("ENCODER", "DECODER"))
    ap.add_argument("--device", default="auto",
                    help="onnxruntime device: auto, cpu, cuda, tensorrt, webgpu, directml, coreml")
    ap.add_argument("--points-per-side", type=int, default=32)
    ap.add_argument("--points-per-batch", type=int, default=64)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=2, help="images timed after one warm-up (the median is printed)")
    args = ap.parse_args(argv)
    from r360gpu.probes.onnx_models import EMBEDDINGS, SamModels
    from r360gpu.probes.sam_amg import generate_masks

    width, height = (int(v) for v in args.size.lower().split("x"))
    image = scene(np.random.default_rng(args.seed), width, height)
    models, load_s, _ = timed(lambda: SamModels(*args.onnx, device=args.device))
    # The random-weight exports keep nothing at SAM's defaults (see parity_sam.generator_configs).
    params = dataclasses.replace(amg_params(args.points_per_side), points_per_batch=args.points_per_batch)
    walls = []
    for k in range(args.repeat + 1):
        EMBEDDINGS.clear()
        result, wall, cpu = timed(lambda: generate_masks(models, image, params))
        if k:
            walls.append(wall)
    print(f"# r360gpu SAM automatic masks: {models.variant} on {models.provider} (batched decoder: {models.batched}); "
          f"models loaded in {load_s:.1f} s")
    print(f"image {width}x{height}, points {args.points_per_side}x{args.points_per_side}: "
          f"{float(np.median(walls)):.2f} s per image (median of {len(walls)}), {result.count} masks")
    return 0


def amg_params(points_per_side: int):
    """parity_sam's first generator configuration, without importing torch."""
    return P.generator_configs(points_per_side)[0]


def build_model(args, image):
    """(official(params) -> masks, {run: (encoder, decoder)}, the torch-driven SamModels or None,
    generator parameters, label) for --model."""
    work = Path(args.work)
    if args.model == "sam":
        sam = P.build_sam(args.seed)
        enc, dec1 = P.export_onnx(sam, work, batched_decoder=False, reuse=args.reuse_exports)
        _, dec_b = P.export_onnx(sam, work, batched_decoder=True, reuse=True)
        sam.to(args.torch_device)  # exported on the CPU; the official generator runs where the model is
        return (lambda params: P.official_generate(sam, image, params)[0], {"before": (enc, dec1), "after": (enc, dec_b)}, None,
                P.generator_configs(args.points_per_side)[0], "ViT-B")
    import parity_sam2 as P2

    model = P2.build_sam2(args.seed)
    enc, dec = work / "sam2.1_hiera_t_random.encoder.onnx", work / "sam2.1_hiera_t_random.decoder.onnx"
    if not (args.reuse_exports and enc.is_file() and dec.is_file()):
        enc, dec = P2.export_onnx(model, work)
    return (lambda params: P2.official_generate(model, image, params, None), {"after": (enc, dec)},
            P2.TorchSam2Models(model), P2.generator_configs(args.points_per_side)[0], "SAM 2.1 Hiera-Tiny")


def main() -> int:
    if "--onnx" in sys.argv[1:]:
        return onnx_only(sys.argv[1:])
    args = parse_args()
    tv = P.use_torchvision_or_standin()
    sys.path.insert(0, str(Path(args.sam_src or args.gsam2_src).resolve()))
    sys.path.insert(0, str(Path(args.samexporter_src).resolve()))
    import dataclasses

    import torch

    from r360gpu.probes.onnx_models import EMBEDDINGS
    from r360gpu.probes.sam_amg import generate_masks

    torch.set_num_threads(max(1, os.cpu_count() or 2))
    width, height = (int(v) for v in args.size.lower().split("x"))
    rng = np.random.default_rng(args.seed)
    image = scene(rng, width, height)
    t0 = time.perf_counter()
    official, pairs, algorithm, params, label = build_model(args, image)
    pairs["unhoisted"] = pairs["after"]
    params = dataclasses.replace(params, points_per_batch=args.points_per_batch)
    gpu = torch.cuda.get_device_name() if args.torch_device.startswith("cuda") else "CPU"
    print(f"# SAM automatic masks: official (torch {torch.__version__} on {args.torch_device}: {gpu}, {tv}) vs "
          f"r360gpu (onnxruntime, probe device {args.probe_device})")
    print(f"machine: {os.cpu_count()} CPU cores; {load()}; exports ready in {time.perf_counter() - t0:.0f} s")
    print(f"image {width}x{height}; {label} random weights, seed {args.seed}; points {params.points_per_side}x"
          f"{params.points_per_side}, batch {params.points_per_batch}, mask_threshold {params.mask_threshold}, "
          f"pred_iou_thresh {params.pred_iou_thresh}, stability >= {params.stability_score_thresh} (offset "
          f"{params.stability_score_offset}), box_nms {params.box_nms_thresh}")

    masks, times = {}, {}
    for run in [r.strip() for r in args.runs.split(",") if r.strip()]:
        if run == "official":
            generate = lambda: official(params)  # noqa: E731
        elif run == "algorithm" and algorithm is not None:
            generate = lambda: generate_masks(algorithm, image, params).masks  # noqa: E731
        elif run in pairs:
            models = load_models(*pairs[run], before=run == "before", hoist=run != "unhoisted",
                                 device=args.probe_device)
            print(f"  {run} runs on {models.provider}")
            generate = lambda: generate_masks(models, image, params).masks  # noqa: E731
        else:
            raise SystemExit(f"unknown run {run!r}; use official, {', '.join(pairs)}"
                             f"{', algorithm' if algorithm is not None else ''}")
        for _ in range(2 if args.warmup else 1):
            EMBEDDINGS.clear()  # every generator encodes its image itself
            m, wall, cpu = timed(generate)
        masks[run], times[run] = m, (wall, cpu)
        print(f"  {run:8s}: {wall:7.1f} s wall, {cpu:7.1f} CPU-s, {len(m)} masks   ({load()})", flush=True)

    print("mask sets (Hungarian matching on IoU):")
    names = list(masks)
    equal_all = True
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            s = P.match(masks[a], masks[b])
            same = s["n_off"] == s["n_r360"] == s["identical"]
            equal_all &= same
            px = int(np.sum(np.asarray(masks[a]).sum(0) != np.asarray(masks[b]).sum(0))) if same is False and \
                len(masks[a]) == len(masks[b]) else None
            print(f"  {a} vs {b}: {s['n_off']} / {s['n_r360']} masks, {s['identical']} pixel-identical pairs, "
                  f"min IoU {s['min_iou']:.4f} -> {'EQUAL' if same else 'DIFFERENT'}"
                  f"{f' (mask-count maps differ at {px} pixels)' if px is not None else ''}")

    if "after" in times:
        models = load_models(*pairs["after"], before=False, device=args.probe_device)
        EMBEDDINGS.clear()
        _, enc_wall, enc_cpu = timed(lambda: models.embed(image))
        _, hit_wall, _ = timed(lambda: models.embed(image))
        print(f"shared encoding: a second probe on the same SAM encoder gets the view's embedding in "
              f"{hit_wall * 1000:.0f} ms instead of {enc_wall:.1f} s wall ({enc_cpu:.1f} CPU-s)")
        EMBEDDINGS.clear()

    print("ratios (official or before / after):")
    for peer in ("official", "before"):
        if peer in times and "after" in times:
            print(f"  {peer:8s}/after: wall {times[peer][0] / times['after'][0]:.2f}x, "
                  f"CPU {times[peer][1] / times['after'][1]:.2f}x")
    per_view = SCENES * METHODS * VIEWS
    print(f"projected structural probe of the paper's benchmark ({SCENES} scenes x {METHODS} methods x {VIEWS} "
          f"views; post + reference rendering per view = {2 * per_view} images; {per_view + SCENES * VIEWS} "
          f"when each scene's references are probed once), one process on this machine:")
    for run, (wall, cpu) in times.items():
        print(f"  {run:8s}: {hours(2 * per_view * wall)} ({hours((per_view + SCENES * VIEWS) * wall)} with "
              f"references once)  [{wall:.1f} s per image]")
    print(f"mask sets {'all EQUAL' if equal_all else 'NOT all equal'}")
    return 0 if equal_all else 1


if __name__ == "__main__":
    raise SystemExit(main())
