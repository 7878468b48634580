"""The measure stage of one view: every method at once.

Given the probe outputs already at hand (a :class:`MeasureJob`) and how the run
measures (:class:`MeasureSettings`, the same for every view), :func:`measure_view_methods` returns
each method's :class:`~r360gpu.metrics.record.ViewRecord` and boundary-sweep
rows, computing what the methods share once per view:

* fidelity: I_ref is prepared once (:func:`~r360gpu.metrics.fidelity.fidelity_views`);
* geometric: D_pre and M^v are uploaded once and the GPU passes of all methods
  share one submission (:func:`~r360gpu.metrics.geometric.acc_depth_views`);
* boundary sweep: M^v is eroded / dilated and uploaded once
  (:func:`~r360gpu.metrics.sensitivity.boundary_targets`).

The values equal the per-method functions (semantic_view, structural_view,
acc_depth_view, fidelity_view, boundary_sensitivity) called one method at a
time (tests/test_metrics_measure.py).
"""
from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..kernels import mask_iou as K
from .fidelity import LpipsModel, fidelity_views
from .geometric import GeometricView, GhtParams, acc_depth_views
from .record import ViewRecord
from ..protocol import XI_DEFAULT
from .semantic import semantic_view
from .sensitivity import NOT_GIVEN, BoundaryInput, BoundarySweep, boundary_sensitivity, boundary_targets
from .structural import check_mode, structural_view


@dataclass
class MethodOutputs:
    """One method's renderings and probe outputs on one view.

    rgb: I_post (H, W, 3); depth: D_post (H, W) or None.
    semantic: {semantic probe name: prediction on I_post}.
    structural: {structural probe name: masks on I_post}.
    """

    rgb: np.ndarray
    depth: np.ndarray | None = None
    semantic: Mapping[str, object] = field(default_factory=dict)
    structural: Mapping[str, object] = field(default_factory=dict)


@dataclass
class MethodMeasures:
    """What the measure stage gives per method: the record, the boundary rows
    ({row: {label: value}}, None when the sweep is off or lacks a probe) and the
    GeometricView (for pictures; None without depths)."""

    record: ViewRecord
    boundary: dict | None
    geometric: GeometricView | None


@dataclass
class MeasureJob:
    """One view to measure: its target, the methods' outputs and what they are compared with.

    target: M^v (H, W).  methods: {method: MethodOutputs}.  semantic_pre: {probe: prediction on
    I_pre}, in probe order.  structural_first: {probe: masks} on I_ref (mode "reference") or on
    I_pre ("reference_free"), in probe order.  pre_depth: D_pre or None; ref_rgb: I_ref or None
    (no fidelity).
    """

    view: str
    scene: str
    target: object
    methods: Mapping[str, MethodOutputs]
    semantic_pre: Mapping[str, object]
    structural_first: Mapping[str, object]
    pre_depth: object = None
    ref_rgb: object = None


@dataclass(frozen=True)
class MeasureSettings:
    """How every view of a run is measured: the structural mode, the probe descriptions for the
    records, the boundary sweep (on or off), the xi sweep, the compat depth rule, GHT's parameters,
    the LPIPS model (None: no LPIPS) and the GPU context."""

    mode: str
    probes: Sequence[dict] = ()
    boundary: bool = True
    xis: Sequence[float] = (XI_DEFAULT,)
    compat: bool = False
    ght_params: GhtParams = GhtParams()
    lpips_model: LpipsModel | None = None
    ctx: object = None


def measure_view_methods(job: MeasureJob, settings: MeasureSettings) -> dict[str, MethodMeasures]:
    """Measure every method of one view (see the module docstring).

    The boundary sweep uses the first semantic and the first structural probe, and runs only when
    both exist (and ``settings.boundary``).
    """
    view, scene, target, methods = job.view, job.scene, job.target, job.methods
    semantic_pre, structural_first, pre_depth, ref_rgb = (job.semantic_pre, job.structural_first, job.pre_depth,
                                                          job.ref_rgb)
    mode, probes, boundary, xis = settings.mode, settings.probes, settings.boundary, settings.xis
    compat, ght_params, lpips_model, ctx = settings.compat, settings.ght_params, settings.lpips_model, settings.ctx
    check_mode(mode)
    names = list(methods)
    sem_names, str_names = list(semantic_pre), list(structural_first)
    with _Fidelity(methods, ref_rgb, lpips_model, ctx) as fidelity:
        geo: dict[str, GeometricView] = {}
        with_depth = [m for m in names if pre_depth is not None and methods[m].depth is not None]
        if with_depth:
            views = acc_depth_views(pre_depth, [methods[m].depth for m in with_depth], target, compat=compat,
                                    ght_params=ght_params, ctx=ctx)
            geo = dict(zip(with_depth, views))
        sweep = boundary and bool(sem_names) and bool(str_names)
        if sweep:
            boundary_targets(target, ctx=ctx)  # once for all methods (memoised)
        parts = {}
        packs = K.PackMemo(ctx)  # the first rendering's masks serve every method: packed once
        for m in names:
            mo = methods[m]
            sem_views = [semantic_view(semantic_pre[p], mo.semantic[p], target, view=view, ctx=ctx)
                         for p in sem_names]
            if mode == "reference":
                pairs = {p: (mo.structural[p], structural_first[p]) for p in str_names}
            else:
                pairs = {p: (structural_first[p], mo.structural[p]) for p in str_names}
            str_views = [structural_view(a, b, target, mode=mode, view=view, ctx=ctx, packs=packs)
                         for a, b in pairs.values()]
            g = geo.get(m)
            rows = None
            if sweep:
                a, b = pairs[str_names[0]]
                table = boundary_sensitivity(
                    [BoundaryInput(target, pred_pre=semantic_pre[sem_names[0]], pred_post=mo.semantic[sem_names[0]],
                                   masks_a=a, masks_b=b, geometric=g if g is not None else NOT_GIVEN, view=view)],
                    BoundarySweep(geometric=g is not None, structural_mode=mode, xis=xis, compat=compat,
                                  ght_params=ght_params),
                    ctx=ctx, packs=packs,
                )
                rows = {row: table.row(row) for row in table.rows}
            parts[m] = (sem_views, str_views, g, rows)
        fid = fidelity.result()
    out = {}
    for m, (sem_views, str_views, g, rows) in parts.items():
        record = ViewRecord.build(view, scene, m, probes=probes, semantic=sem_views, structural=str_views,
                                  geometric=g, fidelity=fid.get(m))
        out[m] = MethodMeasures(record, rows, g)
    return out


class _Fidelity:
    """The view's fidelity_views (every method against I_ref; none without I_ref), as a context:
    in a background thread when SSIM runs on the host (its OpenCV filters release the GIL, so
    the depth and mask passes overlap them), inline on the GPU backend (one thread submits).
    Leaving the context waits for the thread, so it never outlives the view's arrays."""

    _pool = None
    _pool_lock = threading.Lock()

    def __init__(self, methods: Mapping[str, MethodOutputs], ref_rgb, lpips_model, ctx):
        import contextvars

        from ..gpu import get_context
        from ..kernels.ssim import ssim_backend

        self._names = list(methods) if ref_rgb is not None else []
        self._fut, self._views = None, []
        if not self._names:
            return
        ctx = ctx or get_context()
        args = ([methods[m].rgb for m in self._names], ref_rgb, lpips_model)
        kw = {"ctx": ctx, "what": [f"method {m}'s I_post" for m in self._names]}
        if ssim_backend(ctx) == "cpu":
            self._fut = _Fidelity._thread().submit(contextvars.copy_context().run, fidelity_views, *args, **kw)
        else:
            self._views = fidelity_views(*args, **kw)

    @classmethod
    def _thread(cls):
        """The process's one fidelity thread (made on first use; measured views may come from several threads)."""
        with cls._pool_lock:
            if cls._pool is None:
                from concurrent.futures import ThreadPoolExecutor

                cls._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="r360-fidelity")
            return cls._pool

    def result(self) -> dict:
        """{method: FidelityView} (errors of the thread are raised here)."""
        return dict(zip(self._names, self._views if self._fut is None else self._fut.result()))

    def __enter__(self) -> "_Fidelity":
        return self

    def __exit__(self, *exc) -> None:
        if self._fut is not None:
            from concurrent.futures import wait

            wait([self._fut])  # its error, if the caller's own came first, is dropped
