"""The batched measure stage equals the per-method functions called one at a time."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.metrics.fidelity import fidelity_view
from r360gpu.metrics.geometric import acc_depth_view
from r360gpu.metrics.measure import MeasureJob, MeasureSettings, MethodOutputs, measure_view_methods
from r360gpu.metrics.record import ViewRecord
from r360gpu.metrics.semantic import semantic_view
from r360gpu.metrics.sensitivity import NOT_GIVEN, BoundaryInput, BoundarySweep, boundary_sensitivity
from r360gpu.metrics.structural import structural_view


def _blobs(rng, k, h, w):
    yy, xx = np.mgrid[:h, :w]
    out = np.zeros((k, h, w), bool)
    for i in range(k):
        cy, cx, r = rng.uniform(0, h), rng.uniform(0, w), rng.uniform(3, 20)
        out[i] = (yy - cy) ** 2 + (xx - cx) ** 2 < r * r
    return out


@pytest.mark.parametrize("mode", ["reference", "reference_free"])
def test_batched_equals_per_method(ctx, mode):
    rng = np.random.default_rng(3)
    h, w = 60, 83
    target = _blobs(rng, 1, h, w)[0]
    pre_depth = rng.uniform(1, 5, (h, w)).astype(np.float32)
    ref = rng.random((h, w, 3)).astype(np.float32)
    sem_pre = {"s": _blobs(rng, 2, h, w)}
    first = {"t": _blobs(rng, 4, h, w)}
    methods = {}
    for i, name in enumerate(["a", "b", "c"]):
        d = pre_depth.copy()
        d[target] += i
        methods[name] = MethodOutputs(
            rgb=np.clip(ref + rng.normal(0, 0.05 * i, ref.shape), 0, 1).astype(np.float32),
            depth=None if name == "c" else d,
            semantic={"s": _blobs(rng, i, h, w)},
            structural={"t": _blobs(rng, 3, h, w)},
        )
    got = measure_view_methods(MeasureJob(view="v", scene="sc", target=target, methods=methods,
                                          semantic_pre=sem_pre, structural_first=first, pre_depth=pre_depth,
                                          ref_rgb=ref), MeasureSettings(mode=mode, xis=(0.3, 0.5), ctx=ctx))
    for name, mo in methods.items():
        sem = [semantic_view(sem_pre["s"], mo.semantic["s"], target, view="v", ctx=ctx)]
        a, b = (mo.structural["t"], first["t"]) if mode == "reference" else (first["t"], mo.structural["t"])
        stv = [structural_view(a, b, target, mode=mode, view="v", ctx=ctx)]
        geo = acc_depth_view(pre_depth, mo.depth, target, ctx=ctx) if mo.depth is not None else None
        rec = ViewRecord.build("v", "sc", name, semantic=sem, structural=stv, geometric=geo,
                               fidelity=fidelity_view(mo.rgb, ref, ctx=ctx))
        assert got[name].record.to_dict() == rec.to_dict()
        table = boundary_sensitivity(
            [BoundaryInput(target, pred_pre=sem_pre["s"], pred_post=mo.semantic["s"], masks_a=a, masks_b=b,
                           geometric=geo if geo is not None else NOT_GIVEN, view="v")],
            BoundarySweep(geometric=geo is not None, structural_mode=mode, xis=(0.3, 0.5)), ctx=ctx)
        assert got[name].boundary == {row: table.row(row) for row in table.rows}
        assert (got[name].geometric is None) == (geo is None)


def test_without_reference_depth_or_probes(ctx):
    rng = np.random.default_rng(5)
    target = _blobs(rng, 1, 20, 30)[0]
    settings = MeasureSettings(mode="reference", ctx=ctx)
    got = measure_view_methods(MeasureJob(view="v", scene="sc", target=target,
                                          methods={"m": MethodOutputs(rgb=np.zeros((20, 30, 3), np.uint8))},
                                          semantic_pre={}, structural_first={}), settings)
    r = got["m"]
    assert r.boundary is None and r.geometric is None
    assert r.record.fidelity is None and r.record.geometric is None
    assert measure_view_methods(MeasureJob(view="v", scene="sc", target=target, methods={}, semantic_pre={},
                                           structural_first={}), settings) == {}


@pytest.mark.parametrize("ssim_backend", ["cpu", "gpu"])
def test_fidelity_overlap_keeps_values_and_errors(ctx, monkeypatch, ssim_backend):
    """On the cpu SSIM backend fidelity runs in its own thread while the depth and mask passes
    run here; the records are the same as on the inline path, and an error in that thread
    (a NaN I_post) reaches the caller, naming the method."""
    import threading

    import r360gpu.metrics.fidelity as fidelity
    from r360gpu.errors import InputError

    monkeypatch.setenv("R360GPU_SSIM", ssim_backend)
    rng = np.random.default_rng(8)
    h, w = 40, 57
    target = _blobs(rng, 1, h, w)[0]
    ref = rng.random((h, w, 3)).astype(np.float32)
    pre_depth = rng.uniform(1, 5, (h, w)).astype(np.float32)
    methods = {m: MethodOutputs(rgb=np.clip(ref + rng.normal(0, 0.1, ref.shape), 0, 1).astype(np.float32),
                                depth=pre_depth + i) for i, m in enumerate("ab")}
    threads = []
    real = fidelity.fidelity_views

    def spy(*a, **k):
        threads.append(threading.current_thread().name)
        return real(*a, **k)

    monkeypatch.setattr("r360gpu.metrics.measure.fidelity_views", spy)
    kw = dict(view="v", scene="sc", target=target, semantic_pre={}, structural_first={}, pre_depth=pre_depth,
              ref_rgb=ref)
    settings = MeasureSettings(mode="reference", ctx=ctx)
    got = measure_view_methods(MeasureJob(methods=methods, **kw), settings)
    assert threads == (["r360-fidelity_0"] if ssim_backend == "cpu" else [threading.current_thread().name])
    for m, mo in methods.items():
        assert got[m].record.fidelity == fidelity_view(mo.rgb, ref, ctx=ctx)
    bad = dict(methods)
    bad["b"] = MethodOutputs(rgb=np.where(target[:, :, None], np.nan, ref).astype(np.float32), depth=pre_depth)
    with pytest.raises(InputError, match="method b's I_post contains NaN"):
        measure_view_methods(MeasureJob(methods=bad, **kw), settings)
