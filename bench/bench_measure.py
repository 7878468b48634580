"""The measure stage at 1920x1080: every method of one view (three axes,
PSNR/SSIM, boundary sweep E15..D15) with r360gpu.metrics.measure, against the
previous implementation measured in the same run.

The previous implementation, rebuilt here from the functions it used: per
method, float64 SSIM through cv2.sepFilter2D (metrics.fidelity.ssim) and a
float64 MSE, the depth passes with their own uploads and waits, and a sweep
doing one cv2.erode / cv2.dilate and one upload per offset and one IoU call
per offset and axis.  Probe outputs are synthetic blobs (one semantic probe,
one structural probe with 6 masks per rendering; bool, as the probes hand them over), so only the measuring is
timed.  Images are float32, as the renderer and the renders reader give them.
Last, both SSIM backends (the WGSL kernel and the OpenCV path) are timed on
this adapter.

    python bench/bench_measure.py [--methods 3] [--width 1920] [--height 1080] [--repeat 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import blob_masks, header  # noqa: E402


def make_view(h, w, n_methods, rng):
    """One view's inputs; probe masks are bool, as MaskSet and SemanticPrediction hold them."""
    from r360gpu.metrics.measure import MethodOutputs

    target = blob_masks(1, h, w, rng)[0].astype(bool)

    def probe_masks(n):
        return blob_masks(n, h, w, rng).astype(bool)

    ref = (rng.random((h, w, 3)) * 0.2 + np.linspace(0, 0.8, w)[None, :, None]).astype(np.float32)
    pre_depth = (3 + rng.normal(0, 0.01, (h, w))).astype(np.float32)
    pre_depth[target] = 2.0
    methods = {}
    for i in range(n_methods):
        depth = pre_depth.copy()
        depth[target] = 3.0 + 0.1 * i
        rgb = np.clip(ref + rng.normal(0, 0.02 * (i + 1), ref.shape).astype(np.float32), 0, 1)
        methods[f"m{i}"] = MethodOutputs(rgb=rgb, depth=depth, semantic={"sem": probe_masks(1 + i % 2)},
                                         structural={"str": probe_masks(6)})
    return target, ref, pre_depth, {"sem": probe_masks(2)}, {"str": probe_masks(6)}, methods


def previous_way(target, ref, pre_depth, sem_pre, first, methods, ctx):
    """One method at a time, as the code before the batched kernels did."""
    from r360gpu.kernels import mask_iou as K
    from r360gpu.kernels.morph import perturb_reference
    from r360gpu.metrics import fidelity as F
    from r360gpu.metrics.geometric import acc_depth_view
    from r360gpu.metrics.semantic import predicted_unions, semantic_view, semantic_view_from_unions
    from r360gpu.metrics.sensitivity import BOUNDARY_OFFSETS
    from r360gpu.metrics.structural import retained, structural_from_ious, structural_view

    out = {}
    for name, mo in methods.items():
        sem = semantic_view(sem_pre["sem"], mo.semantic["sem"], target, ctx=ctx)
        a, b = mo.structural["str"], first["str"]
        stv = structural_view(a, b, target, mode="reference", ctx=ctx)
        geo = acc_depth_view(pre_depth, mo.depth, target, ctx=ctx)
        x, y = F._pair(mo.rgb, ref)
        fid = (float(np.mean((x - y) ** 2)), F.ssim(x, y))
        packed = {o: K.pack(perturb_reference(target, o), ctx=ctx) for o in BOUNDARY_OFFSETS}
        u_pre, u_post, counts = predicted_unions(sem_pre["sem"], mo.semantic["sem"], target.shape, ctx=ctx)
        preds = K.pack(np.stack([u_pre, u_post]), ctx=ctx)
        rows = []
        pa, pb = K.pack(a, ctx=ctx), K.pack(b, ctx=ctx)
        iou_ab = K.mask_iou(pa, pb, ctx=ctx).iou
        for o in BOUNDARY_OFFSETS:
            s = semantic_view_from_unions(preds, packed[o], n_instances=counts, ctx=ctx)
            r = K.mask_iou(geo.changed, packed[o], ctx=ctx)
            ra, rb = K.mask_iou(pa, packed[o], ctx=ctx), K.mask_iou(pb, packed[o], ctx=ctx)
            ka, kb = retained(ra.iou[:, 0]), retained(rb.iou[:, 0])
            st = structural_from_ious(ka, kb, iou_ab[np.ix_(ka, kb)], area_target=int(rb.area_b[0]), mode="reference")
            rows.append((s.iou_post, int(r.intersection[0, 0]), st.sim_sam))
        out[name] = (sem.iou_post, stv.sim_sam, geo.acc_depth, fid, rows)
    return out


def batched(target, ref, pre_depth, sem_pre, first, methods, ctx):
    from r360gpu.metrics.measure import MeasureJob, MeasureSettings, measure_view_methods
    from r360gpu.metrics.sensitivity import _TARGETS

    _TARGETS.clear()  # each view is new: the sweep's targets are recomputed
    return measure_view_methods(MeasureJob(view="v", scene="s", target=target, methods=methods, semantic_pre=sem_pre,
                                           structural_first=first, pre_depth=pre_depth, ref_rgb=ref),
                                MeasureSettings(mode="reference", ctx=ctx))


def best_of(fn, repeat):
    fn()  # warm-up: shader compilation, buffer pools
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--methods", type=int, default=3)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    from r360gpu.gpu import get_context
    from r360gpu.kernels.ssim import ssim_backend

    header("measure stage benchmark (one view, all methods)")
    ctx = get_context()
    print(f"SSIM backend: {ssim_backend(ctx)}; best of {args.repeat} runs; load average before: "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    rng = np.random.default_rng(0)
    target, ref, pre_depth, sem_pre, first, methods = make_view(args.height, args.width, args.methods, rng)
    one = dict(list(methods.items())[:1])
    rows = []
    for label, ms in ((f"1 method", one), (f"{args.methods} methods", methods)):
        t_prev = best_of(lambda: previous_way(target, ref, pre_depth, sem_pre, first, ms, ctx), args.repeat)
        t_new = best_of(lambda: batched(target, ref, pre_depth, sem_pre, first, ms, ctx), args.repeat)
        rows.append((label, len(ms), t_prev, t_new))
    # The two ways agree (SSIM within the backend's tolerance, the rest exactly).
    new = batched(target, ref, pre_depth, sem_pre, first, methods, ctx)
    old = previous_way(target, ref, pre_depth, sem_pre, first, methods, ctx)
    for name in methods:
        rec = new[name].record
        assert rec.geometric["acc_depth"] == old[name][2]
        assert abs(rec.fidelity.ssim - old[name][3][1]) < 1e-4
    print(f"\nview {args.width}x{args.height}\n{'workload':<14}{'previous (ms/method)':>22}{'batched (ms/method)':>22}"
          f"{'speed-up':>10}")
    for label, n, tp, tn in rows:
        print(f"{label:<14}{tp / n * 1e3:>22.1f}{tn / n * 1e3:>22.1f}{tp / tn:>9.1f}x")
    # Why CPU adapters take the OpenCV path: both SSIM backends on this adapter.
    from r360gpu.kernels.ssim import ssim_mse_many

    posts = [mo.rgb for mo in methods.values()]
    t_b = {b: best_of(lambda: ssim_mse_many(posts, ref, ctx=ctx, backend=b), 2) for b in ("gpu", "cpu")}
    print(f"{'SSIM + MSE, ' + str(len(posts)) + ' methods':<26}{'gpu kernel':>12}{'cpu (OpenCV)':>14}{'gpu / cpu':>11}")
    print(f"{'ms per method':<26}{t_b['gpu'] / len(posts) * 1e3:>12.1f}{t_b['cpu'] / len(posts) * 1e3:>14.1f}"
          f"{t_b['gpu'] / t_b['cpu']:>10.1f}x")
    per = rows[-1][3] / rows[-1][1] * 1e3
    print(f"goal: <= 60 ms per method-view on lavapipe: {'met' if per <= 60 else 'NOT met'} ({per:.0f} ms)"
          f"; load average after: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
