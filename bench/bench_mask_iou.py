"""Mask IoU matrix: r360gpu vs pycocotools vs a per-pair numpy loop (same run, same inputs).

From dense uint8 masks (N x H x W) to the N x M IoU matrix, 64 vs 64 realistic
blob masks at 1920x1080 by default.  Also compares the two ways of packing
host masks (CPU np.packbits + upload vs upload of u32 pixels + GPU pack).

    python bench/bench_mask_iou.py [--n 64] [--width 1920] [--height 1080] [--repeat 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import blob_masks, header, timeit  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--loop-pairs", type=int, default=0,
                    help="pairs timed for the per-pair loop (0 = all N*N; the rate is scaled to all pairs)")
    args = ap.parse_args()

    from pycocotools import mask as coco

    from r360gpu.gpu import get_context
    from r360gpu.kernels import mask_iou as K

    header("mask IoU benchmark")
    ctx = get_context()
    rng = np.random.default_rng(0)
    n, h, w = args.n, args.height, args.width
    a = blob_masks(n, h, w, rng)
    b = blob_masks(n, h, w, rng)
    print(f"inputs: {n} x {n} blob masks at {w}x{h}, mean area {a.mean() * 100:.2f}% of the frame\n")

    t_gpu, r = timeit(lambda: K.mask_iou(a, b, ctx=ctx), args.repeat)

    def pycocotools_iou():
        ra = coco.encode(np.asfortranarray(a.transpose(1, 2, 0)))
        rb = coco.encode(np.asfortranarray(b.transpose(1, 2, 0)))
        return coco.iou(ra, rb, [0] * n)

    t_coco, iou_coco = timeit(pycocotools_iou, args.repeat)
    assert np.abs(np.asarray(iou_coco) - r.iou).max() < 1e-9, "pycocotools disagrees"

    pairs = [(i, j) for i in range(n) for j in range(n)]
    if args.loop_pairs:
        pairs = pairs[: args.loop_pairs]
    ab, bb = a.astype(bool), b.astype(bool)
    t0 = time.perf_counter()
    for i, j in pairs:
        inter = np.logical_and(ab[i], bb[j]).sum()
        union = np.logical_or(ab[i], bb[j]).sum()
        v = inter / union if union else 0.0
        assert abs(v - r.iou[i, j]) < 1e-12
    t_loop = (time.perf_counter() - t0) * (n * n) / len(pairs)

    # Packing: CPU packbits + upload of 1 bit/pixel, vs upload of 4 bytes/pixel + GPU pack.
    t_cpu_pack, _ = timeit(lambda: K.pack(a, ctx=ctx), args.repeat)
    a32 = a.astype(np.uint32)

    def gpu_pack():
        buf = ctx.buffer(a32)
        return K.pack(K.DeviceMasks(buf, n, h, w), ctx=ctx)

    t_gpu_pack, p = timeit(gpu_pack, args.repeat)
    assert (K.to_host(p, ctx=ctx) == K.pack_bits(a)).all()

    print(f"{'method':<34}{'time (ms)':>12}{'r360gpu speed-up':>20}")
    print(f"{'r360gpu (GPU)':<34}{t_gpu * 1e3:>12.1f}{1.0:>19.1f}x")
    print(f"{'pycocotools encode + iou':<34}{t_coco * 1e3:>12.1f}{t_coco / t_gpu:>19.1f}x")
    print(f"{'numpy per-pair loop':<34}{t_loop * 1e3:>12.1f}{t_loop / t_gpu:>19.1f}x")
    print()
    print(f"packing one stack: CPU np.packbits + upload {t_cpu_pack * 1e3:.1f} ms; "
          f"upload u32 pixels + GPU pack {t_gpu_pack * 1e3:.1f} ms (ratio {t_gpu_pack / t_cpu_pack:.1f})")
    goals = [("vs pycocotools >= 5x", t_coco / t_gpu >= 5), ("vs per-pair loop >= 100x", t_loop / t_gpu >= 100)]
    print("goals: " + ", ".join(f"{g}: {'met' if ok else 'NOT met'}" for g, ok in goals))
    return 0


if __name__ == "__main__":
    sys.exit(main())
