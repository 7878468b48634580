"""One view's geometric axis at 1920x1080: r360gpu vs the reference pipeline's way.

The reference way (public Remove360 code): |dD| -> matplotlib imsave(cmap=gray_r)
PNG -> read back with PIL -> numpy histogram of the gray levels -> GHT ->
``gray < t`` -> |changed & M| / |M|.  r360gpu: dD, min/max, histogram and the
changed count on the GPU, GHT on the host; one view alone, and one view's
methods through acc_depth_views (one submission per pass for all methods);
the kernels alone (fixed split, no GHT) one method at a time and batched;
and the host path CPU adapters take for numpy depths (same float32 arithmetic).  Every row is the best of --repeat runs (the
machine may be shared: the load average is printed).

    python bench/bench_depth.py [--width 1920] [--height 1080] [--repeat 5] [--methods 3]
"""
from __future__ import annotations

import argparse
import io
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import header  # noqa: E402


def best_of(fn, repeat):
    res = fn()  # warm-up
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        res = fn()
        best = min(best, time.perf_counter() - t)
    return best, res


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
    ap.add_argument("--methods", type=int, default=3)
    args = ap.parse_args()

    from r360gpu.gpu import get_context
    from r360gpu.metrics.geometric import acc_depth_view, acc_depth_views

    header("geometric axis benchmark (one view)")
    ctx = get_context()
    pre, post, mask = synthetic_view(args.height, args.width, np.random.default_rng(0))
    print(f"load average before: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    os.environ["R360GPU_DEPTH_CHANGE"] = "cpu"
    t_host, v_host = best_of(lambda: acc_depth_view(pre, post, mask, ctx=ctx), args.repeat)
    os.environ["R360GPU_DEPTH_CHANGE"] = "gpu"  # the kernel rows run the kernel on any adapter
    t_gpu, v = best_of(lambda: acc_depth_view(pre, post, mask, ctx=ctx), args.repeat)
    assert v_host.summary() == v.summary()
    posts = [post * (1 + 0.01 * k) for k in range(args.methods)]
    t_many, vs = best_of(lambda: acc_depth_views(pre, posts, mask, ctx=ctx), args.repeat)
    from r360gpu.kernels import depth_change as K

    def kernel_batch():
        st = K.delta_histograms(pre, posts, ctx=ctx)
        return K.changed_in_masks(st, mask, [100.0] * len(st), ctx=ctx)

    def kernel_one_by_one():
        return [K.changed_in_mask(K.delta_histogram(pre, d, ctx=ctx), mask, 100.0, ctx=ctx) for d in posts]

    t_kb, _ = best_of(kernel_batch, args.repeat)
    t_k1, _ = best_of(kernel_one_by_one, args.repeat)
    t_compat, vc = best_of(lambda: acc_depth_view(pre, post, mask, compat=True), args.repeat)
    t_ref, acc_ref = best_of(lambda: reference_way(pre, post, mask), args.repeat)
    assert abs(vc.acc_depth - acc_ref) < 1e-12, (vc.acc_depth, acc_ref)
    assert vs[0].summary() == acc_depth_view(pre, posts[0], mask, ctx=ctx).summary()
    t_per = t_many / args.methods
    print(f"view {args.width}x{args.height}: acc_depth float={v.acc_depth:.4f}, compat={vc.acc_depth:.4f}, "
          f"reference={acc_ref:.4f}\n")
    print(f"{'method':<52}{'time (ms)':>12}{'reference / this':>18}")
    rows = (
        ("r360gpu float mode, one view (GPU + host GHT)", t_gpu),
        (f"acc_depth_views, {args.methods} methods, per method", t_per),
        (f"kernels one method at a time (no GHT), per method", t_k1 / args.methods),
        (f"kernels batched over {args.methods} methods (no GHT), per method", t_kb / args.methods),
        ("r360gpu float mode, one view, host path (numpy)", t_host),
        ("r360gpu compat mode (numpy, no PNG)", t_compat),
        ("reference way (matplotlib PNG round trip)", t_ref),
    )
    for label, t in rows:
        print(f"{label:<52}{t * 1e3:>12.1f}{t_ref / t:>17.1f}x")
    best = min(t_gpu, t_per)
    print(f"goal (the kernel): >= 10x faster than the reference way: {'met' if t_ref / best >= 10 else 'NOT met'} "
          f"({t_ref / best:.1f}x); faster than compat: {'yes' if best < t_compat else 'no'}")
    os.environ.pop("R360GPU_DEPTH_CHANGE", None)
    taken = ctx.kernel_backend("depth_change")
    t_taken = t_host if taken == "cpu" else best
    print(f"scoring on this adapter takes the {'host path' if taken == 'cpu' else 'kernel'}: "
          f"{t_ref / t_taken:.1f}x the reference way, {t_compat / t_taken:.1f}x the compat path")
    print(f"load average after: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
