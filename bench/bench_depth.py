"""One view's geometric axis at 1920x1080: r360gpu vs the reference pipeline's way.

The reference way (public Remove360 code): |dD| -> matplotlib imsave(cmap=gray_r)
PNG -> read back with PIL -> numpy histogram of the gray levels -> GHT ->
``gray < t`` -> |changed & M| / |M|.  r360gpu: dD, min/max, histogram and the
changed count on the GPU, GHT on the host.

    python bench/bench_depth.py [--width 1920] [--height 1080] [--repeat 5]
"""
from __future__ import annotations

import argparse
import io
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import header, timeit  # noqa: E402


def synthetic_view(h, w, rng):
    """Depths of a room with a box removed (most of it), plus render noise."""
    yy, xx = np.mgrid[:h, :w].astype(np.float32)
    pre = 4.0 + 0.002 * yy + rng.normal(0, 0.01, (h, w)).astype(np.float32)
    mask = ((xx - w * 0.5) / (w * 0.15)) ** 2 + ((yy - h * 0.55) / (h * 0.2)) ** 2 < 1
    post = pre.copy()
    pre[mask] = 2.5 + 0.001 * xx[mask]
    keep = mask & (xx < w * 0.42)  # residual part of the object
    post[keep] = pre[keep]
    pre[: h // 20] = 0  # no coverage at the top
    return pre.astype(np.float32), post.astype(np.float32), mask


def reference_way(pre, post, mask):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from r360gpu.metrics.ght import ght

    diff = post - pre
    diff[(diff == post) | (diff == -pre)] = 0
    diff = np.abs(diff)
    buf = io.BytesIO()
    plt.imsave(buf, diff, cmap=plt.cm.gray_r, format="png")
    buf.seek(0)
    im = np.array(Image.open(buf))
    gray = np.amax(im[..., :3], axis=-1)
    hist, _ = np.histogram(gray, np.arange(-0.5, 256.5))
    t = ght(hist, np.arange(256)).threshold
    changed = gray < t
    return (changed & mask).sum() / mask.sum()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    from r360gpu.gpu import get_context
    from r360gpu.metrics.geometric import acc_depth_view

    header("geometric axis benchmark (one view)")
    ctx = get_context()
    pre, post, mask = synthetic_view(args.height, args.width, np.random.default_rng(0))
    t_gpu, v = timeit(lambda: acc_depth_view(pre, post, mask, ctx=ctx), args.repeat)
    t_compat, vc = timeit(lambda: acc_depth_view(pre, post, mask, compat=True), args.repeat)
    t_ref, acc_ref = timeit(lambda: reference_way(pre, post, mask), args.repeat)
    assert abs(vc.acc_depth - acc_ref) < 1e-12, (vc.acc_depth, acc_ref)
    print(f"view {args.width}x{args.height}: acc_depth float={v.acc_depth:.4f}, compat={vc.acc_depth:.4f}, "
          f"reference={acc_ref:.4f}\n")
    print(f"{'method':<44}{'time (ms)':>12}{'r360gpu speed-up':>20}")
    print(f"{'r360gpu float mode (GPU + host GHT)':<44}{t_gpu * 1e3:>12.1f}{1.0:>19.1f}x")
    print(f"{'r360gpu compat mode (numpy, no PNG)':<44}{t_compat * 1e3:>12.1f}{t_compat / t_gpu:>19.1f}x")
    print(f"{'reference way (matplotlib PNG round trip)':<44}{t_ref * 1e3:>12.1f}{t_ref / t_gpu:>19.1f}x")
    print(f"goal: >= 10x faster than the reference way: {'met' if t_ref / t_gpu >= 10 else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
