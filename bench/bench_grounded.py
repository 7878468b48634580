"""The grounded probe (GroundingDINO + SAM, ONNX) on an onnxruntime device: per-image wall time, the
providers that ran, the instances found.

    python bench/bench_grounded.py --grounded DINO TOKENIZER SAM_ENCODER SAM_DECODER [--device auto] \\
        [--size 640x480] [--prompt "red sofa"] [--repeat 2]
    python bench/bench_grounded.py --stand-in [--device auto]

``--stand-in`` builds tiny graphs with tests/onnx_graphs.py (a GroundingDINO that returns one fixed
"red sofa" box, SAM's that returns the box): they check the path on the device (the providers that
start, the masks that come back), not the speed.  bench/device_suite.py runs it on the GPU provider.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "tests"))


def stand_in(folder: Path) -> tuple[Path, Path, Path, Path]:
    """(dino, tokenizer.json, SAM encoder, SAM decoder) stand-ins: one query on "red sofa" with its
    box in the image's middle half; SAM's single-mask token fills the box."""
    import onnx_graphs as G

    logits = np.full((1, 256), -np.inf, np.float32)
    logits[0, :5] = -6.0  # caption "red sofa ." -> [CLS] red sofa . [SEP]
    logits[0, 1], logits[0, 2] = 2.0, 3.0  # the phrase "red sofa", over both thresholds
    boxes = np.array([[0.5, 0.5, 0.5, 0.5]], np.float32)
    dino = G.dino_model(folder / "groundingdino.onnx", logits, boxes)
    tok = G.write_tokenizer_json(folder / "tokenizer.json")
    enc = G.sam_encoder_nchw(folder / "sam.encoder.onnx")
    dec = G.sam_decoder(folder / "sam.decoder.onnx", iou=[0.5, 0.9, 0.9, 0.9], shape="box", slope=[1, 1, 1, 1],
                        offset=[0, -1e4, -1e4, -1e4])
    return dino, tok, enc, dec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--grounded", nargs=4, type=Path, metavar=("DINO", "TOKENIZER", "SAM_ENCODER", "SAM_DECODER"))
    src.add_argument("--stand-in", action="store_true", help="tiny stand-in graphs (the path, not the speed)")
    ap.add_argument("--device", default="auto", help="onnxruntime device (r360gpu.probes.providers)")
    ap.add_argument("--size", default="640x480", help="image WIDTHxHEIGHT")
    ap.add_argument("--prompt", default="red sofa")
    ap.add_argument("--repeat", type=int, default=2, help="images timed after one warm-up (the median is printed)")
    args = ap.parse_args(argv)
    from bench_amg import scene

    from r360gpu.probes.base import ProbeView
    from r360gpu.probes.grounded import GroundedSamProbe
    from r360gpu.probes.onnx_models import EMBEDDINGS

    width, height = (int(v) for v in args.size.lower().split("x"))
    image = scene(np.random.default_rng(0), width, height)
    with tempfile.TemporaryDirectory(prefix="r360-grounded-") as tmp:
        files = stand_in(Path(tmp)) if args.stand_in else args.grounded
        t = time.perf_counter()
        probe = GroundedSamProbe(*files, device=args.device)
        load_s = time.perf_counter() - t
        walls = []
        for k in range(args.repeat + 1):
            EMBEDDINGS.clear()  # each image encoded from scratch, as a new view is
            t = time.perf_counter()
            [pred] = probe.predict([ProbeView(f"v{k}", image, "post")], args.prompt)
            if k:
                walls.append(time.perf_counter() - t)
    params = probe.params()
    print(f"# grounded probe{' (stand-in graphs: the path, not the speed)' if args.stand_in else ''}: "
          f"GroundingDINO on {params['dino_provider']}, SAM on {params['provider']}; models loaded in {load_s:.1f} s")
    print(f"image {width}x{height}, prompt {args.prompt!r}: {float(np.median(walls)):.3f} s per image "
          f"(median of {len(walls)}), {pred.count} instance(s) {pred.labels}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
