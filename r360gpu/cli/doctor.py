"""``r360gpu doctor``: which adapter, its limits, and every kernel against its oracle."""
from __future__ import annotations

import os
import time

import numpy as np


def register(sub) -> None:
    p = sub.add_parser(
        "doctor",
        help="show the GPU adapter and check every kernel against its numpy oracle",
        description="Print the adapter and its limits, run every GPU kernel against its numpy "
        "oracle on random data, print pass/fail and timings. Exits 1 on any mismatch.",
    )
    p.add_argument("--adapter", default=None, help="adapter choice (auto, gpu, cpu, or part of its name); "
                   "default: $R360GPU_ADAPTER or auto")
    p.add_argument("--seed", type=int, default=0, help="seed of the random test data (default 0)")
    p.set_defaults(func=run)


def _checks(ctx, rng):
    """(name, callable returning (ok, detail)) for every kernel."""
    from ..kernels import depth_change, mask_iou
    from ..kernels.reference import depth_change_reference, mask_iou_reference, no_depth_in_mask_reference

    def iou_random():
        a = rng.random((6, 67, 45)) < 0.3
        b = rng.random((5, 67, 45)) < 0.4
        a[0] = False
        r = mask_iou.mask_iou(a, b, ctx=ctx)
        inter, aa, ab, iou = mask_iou_reference(a, b)
        ok = (r.intersection == inter).all() and (r.area_a == aa).all() and (r.area_b == ab).all()
        return ok and np.abs(r.iou - iou).max() < 1e-12, f"6x5 masks of 67x45"

    def iou_blobs_1080p():
        h, w = 1080, 1920
        yy, xx = np.mgrid[:h, :w]
        def blobs(n):
            c = rng.uniform([0, 0], [h, w], (n, 2))
            r = rng.uniform(20, 300, n)
            return np.stack([(yy - y) ** 2 + (xx - x) ** 2 < rr**2 for (y, x), rr in zip(c, r)])
        a, b = blobs(8), blobs(8)
        t = time.perf_counter()
        r = mask_iou.mask_iou(a, b, ctx=ctx)
        dt = time.perf_counter() - t
        inter = np.array([[np.count_nonzero(x & y) for y in b] for x in a])
        return (r.intersection == inter).all(), f"8x8 blobs at 1920x1080, GPU {dt * 1e3:.1f} ms"

    def union():
        a = rng.random((4, 33, 70)) < 0.2
        return (mask_iou.union(a, ctx=ctx) == a.any(0)).all(), "4 masks of 33x70"

    def device_pack():
        m = (rng.random((3, 19, 37)) < 0.5).astype(np.uint32)
        buf = ctx.buffer(m)
        r = mask_iou.mask_iou(mask_iou.DeviceMasks(buf, 3, 19, 37), m, ctx=ctx)
        return (r.intersection == mask_iou_reference(m, m)[0]).all(), "3 masks of 19x37 from a device buffer"

    def depth():
        pre = rng.uniform(0.5, 8, (45, 67)).astype(np.float32)
        post = pre.copy()
        sel = rng.random(pre.shape) < 0.3
        post[sel] += 1.5
        pre[0, :5] = 0
        post[1, :5] = np.nan
        mask = rng.random(pre.shape) < 0.5
        st = depth_change.delta_histogram(pre, post, ctx=ctx)
        res = depth_change.changed_in_mask(st, mask, 100.5, ctx=ctx)
        _, lo, hi, hist, changed, n_in, n_m = depth_change_reference(pre, post, mask, 100.5)
        ok = (st.lo, st.hi) == (lo, hi) and (st.hist == hist).all() and (res.changed == changed).all()
        ok = ok and res.n_no_depth_in_mask == no_depth_in_mask_reference(post, mask)
        return ok and (res.n_changed_in_mask, res.n_mask) == (n_in, n_m), "45x67 depths with missing values"

    def ssim_kernel():
        from ..kernels.reference import ssim_reference
        from ..kernels.ssim import SSIM_TOL, ssim_mse_many

        y = rng.integers(0, 256, (23, 37, 3), dtype=np.uint8)
        x = np.clip(y.astype(int) + rng.integers(-40, 41, y.shape), 0, 255).astype(np.uint8)
        (s, m), = ssim_mse_many([x], y, ctx=ctx, backend="gpu")
        rs, rm = ssim_reference(x / 255.0, y / 255.0)
        return abs(s - rs) <= SSIM_TOL["gpu"] and abs(m - rm) <= 1e-12, "23x37 RGB against the window definition"

    def on(backend, fn):
        """fn with the mask and depth kernels forced onto ``backend``: doctor checks the WGSL
        kernels on every adapter, and the host paths scoring takes on CPU adapters."""
        def check():
            from unittest import mock  # here: doctor's module is imported by every command

            with mock.patch.dict(os.environ, {"R360GPU_MASK_IOU": backend, "R360GPU_DEPTH_CHANGE": backend}):
                return fn()
        return check

    checks = [
        ("mask_iou (random)", on("gpu", iou_random)),
        ("mask_iou (blobs, 1080p)", on("gpu", iou_blobs_1080p)),
        ("mask union", on("gpu", union)),
        ("mask_iou (host path)", on("cpu", iou_random)),
        ("mask pack (device buffer)", device_pack),
        ("depth_change", on("gpu", depth)),
        ("depth_change (host path)", on("cpu", depth)),
        ("ssim (GPU kernel)", ssim_kernel),
    ]
    try:
        from ..render import doctor_checks
    except ImportError:
        doctor_checks = None
    if doctor_checks is not None:
        checks.extend(doctor_checks(ctx, rng))
    return checks


def run(args) -> int:
    from ..gpu import get_context

    t0 = time.perf_counter()
    ctx = get_context(args.adapter)
    d = ctx.describe()
    print(f"adapter:  {d['name']} ({d['adapter_type']}, {d['backend']})")
    if d["description"]:
        print(f"driver:   {d['description']}")
    print(f"limits:   storage binding {d['max_binding_bytes'] / 2**20:.0f} MiB, "
          f"{d['max_workgroups_per_dimension']} workgroups per dimension")
    print(f"opened in {time.perf_counter() - t0:.2f} s\n")
    rng = np.random.default_rng(args.seed)
    failed = 0
    for name, check in _checks(ctx, rng):
        t = time.perf_counter()
        try:
            ok, detail = check()
        except Exception as e:  # report every kernel, even after a crash
            ok, detail = False, f"{type(e).__name__}: {e}"
        dt = time.perf_counter() - t
        failed += not ok
        print(f"  {'PASS' if ok else 'FAIL'}  {name:<28} {dt * 1e3:8.1f} ms  {detail}")
    print()
    if failed:
        print(f"{failed} check(s) FAILED on {d['name']}")
        return 1
    print(f"all checks passed on {d['name']}")
    return 0
