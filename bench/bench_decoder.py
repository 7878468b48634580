"""SAM prompt decoders on CPU: the exported graph against the graph whose prompt-independent
work runs once per batch (r360gpu/probes/onnx_hoist.py, what ``SamModels`` opens).

For each ENCODER DECODER pair (a decoder that takes a batch of prompts: bench/parity_sam.py's
``export_onnx(..., batched_decoder=True)``, samexporter's SAM 2 decoder), on a random embedding
and random point prompts, in one process:

* the CPU-seconds of opening the pair with and without the rewrite (its check included);
* whether the rewritten decoder's outputs (``low_res_masks`` / ``masks`` and
  ``iou_predictions`` as ``SamModels`` returns them) are bit-identical to the original's at
  1, 2, 7 and 64 prompts;
* multiply-adds per prompt of both graphs (MatMul, Gemm, Conv, ConvTranspose and their fused
  forms, from the shapes onnxruntime's profiler records in one run of ``--batch`` prompts);
* CPU-ms per prompt (process CPU time, all threads) of ``SamModels.predict_points`` on
  ``--batch`` prompts, the two decoders alternating, ``--repeat`` runs each after one warm-up
  run; medians and their ratio.

    python bench/bench_decoder.py --pair ENCODER DECODER [--pair ENCODER DECODER ...] [--batch 64] [--repeat 5]

Needs onnx and onnxruntime (no torch: the exports come from bench/parity_sam.py and
bench/parity_sam2.py, or any SAM ONNX pair).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from r360gpu.probes.onnx_models import SamEmbedding, SamModels  # noqa: E402

IDENTITY_BATCHES = (1, 2, 7, 64)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pair", nargs=2, action="append", required=True, metavar=("ENCODER", "DECODER"))
    ap.add_argument("--batch", type=int, default=64, help="prompts per decoder run when timing (default 64)")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs of each decoder (default 5)")
    ap.add_argument("--seed", type=int, default=0)
    return ap.parse_args()


def random_embedding(models: SamModels, rng) -> SamEmbedding:
    sam2 = models.variant == "sam2"
    names = ("image_embed", "high_res_feats_0", "high_res_feats_1") if sam2 else ("image_embeddings",)
    features = {}
    for name in names:
        info = models.decoder.inputs[name]
        features[name] = rng.standard_normal([info.fixed(a) for a in range(len(info.shape))]).astype(np.float32)
    # A 640 x 480 image: SAM's resized frame is 1024 x 768 inside the 1024 x 1024 input.
    h, w = 480, 640
    s = models.input_size[0] / max(h, w)
    model_size = models.input_size if models.variant == "sam2" else (round(h * s), round(w * s))
    return SamEmbedding(features, (h, w), model_size)


def points(rng, b: int) -> np.ndarray:
    return rng.uniform(0, 1, (b, 2)) * np.array([640, 480])


def identical(plain: SamModels, hoisted: SamModels, emb, rng) -> str:
    out = []
    for b in IDENTITY_BATCHES:
        pts = points(rng, b)
        a, c = plain.predict_points(emb, pts), hoisted.predict_points(emb, pts)
        same = a.logits.tobytes() == c.logits.tobytes() and a.iou.tobytes() == c.iou.tobytes()
        out.append(f"{b}: {'bit-identical' if same else 'DIFFERENT'}")
    return ", ".join(out)


def _macs(op: str, ins: list, outs: list) -> int:
    """Multiply-adds of one node from the shapes onnxruntime's profiler records (the activations'
    and the output's; it leaves out initializers, so the weights' shapes are inferred): MatMul,
    FusedMatMul, Gemm, FusedGemm: output elements x the inner size; Conv: output elements x input
    channels x (input pixels / output pixels); ConvTranspose: output elements x input channels --
    both exact when the kernel equals the stride (the decoders' mask downscaling, 1x1
    convolutions and upscaling)."""
    if not outs or not ins:
        return 0
    a, out = ins[0], outs[0]
    n_out = int(np.prod(out))
    if op in ("MatMul", "FusedMatMul"):
        return n_out * int(a[-1]) * int(a[-2]) // int(out[-2]) if len(a) >= 2 and len(out) >= 2 else 0
    if op in ("Gemm", "FusedGemm"):
        return n_out * int(a[-1])
    if op in ("Conv", "FusedConv") and len(a) == len(out) >= 3:
        return n_out * int(np.prod(a[1:])) // int(np.prod(out[2:]))
    if op == "ConvTranspose" and len(a) >= 2:
        return n_out * int(a[1])
    return 0


def macs_per_prompt(models: SamModels, emb, rng, b: int) -> float:
    """Multiply-adds per prompt of one decoder run of ``b`` prompts (onnxruntime's profile of that run)."""
    dec = models.decoder
    ort = __import__("onnxruntime")
    options = ort.SessionOptions()
    options.log_severity_level = 3
    options.enable_profiling = True
    with tempfile.TemporaryDirectory() as tmp:
        options.profile_file_prefix = os.path.join(tmp, "decoder")
        session = ort.InferenceSession(dec.model_bytes or str(dec.path), options, providers=["CPUExecutionProvider"])
        feeds = models._feeds(emb, *models._point_prompts(emb, points(rng, b)))
        session.run(models._decoder_outputs(), {k: dec.cast(k, v) for k, v in feeds.items()})
        events = json.loads(Path(session.end_profiling()).read_text())
    total = 0
    for e in events:
        args = e.get("args", {})
        if e.get("cat") != "Node" or "op_name" not in args or not e["name"].endswith("_kernel_time"):
            continue
        shapes = lambda key: [next(iter(d.values())) for d in args.get(key, [])]  # noqa: E731
        total += _macs(args["op_name"], shapes("input_type_shape"), shapes("output_type_shape"))
    return total / b


def main() -> int:
    args = parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"# SAM decoders on CPU: exported graph vs prompt-independent work once per batch ({os.cpu_count()} cores)")
    for enc, dec in args.pair:
        c = time.process_time()
        plain = SamModels(enc, dec, hoist=False)
        c_plain = time.process_time() - c
        c = time.process_time()
        hoisted = SamModels(enc, dec)
        c_hoisted = time.process_time() - c
        print(f"\n## {Path(dec).name} ({plain.variant}; prompt batch {'dynamic' if plain.batched else 'fixed at 1'})")
        print(f"   opening the pair: {c_plain:.2f} CPU-s as exported, {c_hoisted:.2f} CPU-s with the "
              "rewrite and its check at 1 and 3 prompts")
        if not hoisted.hoisted:
            print("   the rewrite does not apply (nothing to hoist, or not bit-identical at the check)")
            continue
        emb = random_embedding(plain, rng)
        print(f"   outputs, rewritten vs exported: {identical(plain, hoisted, emb, rng)}")
        m0, m1 = macs_per_prompt(plain, emb, rng, args.batch), macs_per_prompt(hoisted, emb, rng, args.batch)
        print(f"   multiply-adds per prompt at {args.batch} prompts: {m0 / 1e6:.0f} M -> {m1 / 1e6:.0f} M "
              f"({(m0 - m1) / 1e6:.0f} M, {100 * (m0 - m1) / m0:.0f}% once per batch)")
        pts = points(rng, args.batch)
        cpu = {"exported": [], "rewritten": []}
        for models in (plain, hoisted):
            models.predict_points(emb, pts)  # warm-up: onnxruntime's buffers for this batch size
        load0 = os.getloadavg()[0]
        for _ in range(args.repeat):
            for name, models in (("exported", plain), ("rewritten", hoisted)):
                c = time.process_time()
                models.predict_points(emb, pts)
                cpu[name].append(1000 * (time.process_time() - c) / args.batch)
        a, b = statistics.median(cpu["exported"]), statistics.median(cpu["rewritten"])
        print(f"   CPU-ms per prompt at {args.batch} prompts, medians of {args.repeat} alternating runs "
              f"(load {load0:.1f} -> {os.getloadavg()[0]:.1f}):")
        print(f"     exported  {a:7.1f}   ({', '.join(f'{x:.1f}' for x in cpu['exported'])})")
        print(f"     rewritten {b:7.1f}   ({', '.join(f'{x:.1f}' for x in cpu['rewritten'])})")
        print(f"     ratio     {a / b:7.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
