"""From per-view records to the axes of each (scene, method) and the results document.

Every axis of a (scene, method) is computed from its per-view records
(:class:`~r360gpu.metrics.record.ViewRecord`):

* ``s_sem``, IoU means: the "most alarming" reading over the semantic probes
  per view (:func:`~r360gpu.metrics.combine.most_alarming_semantic`; with one
  probe that is simply its reading); each probe's own values are kept under
  ``by_probe``.
* ``s_str``: likewise over the structural probes.
* ``s_geo``: mean ``acc_depth^v`` over the views with a non-empty target.
* fidelity: mean PSNR / SSIM / LPIPS against the reference (None without one;
  LPIPS None when no model was given).

Views with an empty target mask are excluded from every axis (and counted),
so all three axes of a cell rest on the same views; ``n_views`` is that count
and weights the view-pooled Overall row.
"""
from __future__ import annotations

import math

import numpy as np

from ..metrics import depth_checks

from ..metrics.combine import most_alarming_semantic, most_alarming_structural
from ..metrics.fidelity import fidelity_summary
from ..metrics.record import ViewRecord
from ..protocol import AXES, XI_SWEEP
from .cells import AxisCells
from .rqs import rqs as rqs_of

def _xi_key(x: float) -> str:
    return f"{x:g}"


def method_axes(records: list[ViewRecord], *, xis=XI_SWEEP, boundary: list[dict] | None = None) -> dict:
    """The axes of one (scene, method) from its per-view records (JSON-ready dict).

    boundary: optional per-view single-view boundary tables ({row: {label: value}}).
    """
    if not records:
        raise ValueError("no views")
    sem_names = list(records[0].semantic)
    str_names = list(records[0].structural)
    out: dict = {"n_views_total": len(records)}
    if sem_names:
        sem = most_alarming_semantic({p: [r.semantic[p] for r in records] for p in sem_names}, xis)
        s = sem.combined
        out.update(
            s_sem=s.s_sem, iou_pre=s.iou_pre, iou_post=s.iou_post, iou_drop=s.iou_drop,
            acc_seg={_xi_key(x): v for x, v in s.acc_seg.items()},
            n_empty_target=s.n_empty_target,
        )
        out["by_probe"] = {"semantic": {p: v.to_dict() for p, v in sem.per_probe.items()}}
        out["most_alarming"] = {"semantic_probe_per_view": list(sem.worst_probe)}
    if str_names:
        st = most_alarming_structural({p: [r.structural[p] for r in records] for p in str_names})
        out.update(s_str=st.combined.s_str, sim_sam=st.combined.sim_sam, structural_mode=st.mode)
        out.setdefault("by_probe", {})["structural"] = {p: v.to_dict() for p, v in st.per_probe.items()}
        out.setdefault("most_alarming", {})["structural_probe_per_view"] = list(st.worst_probe)
    geo = [r.geometric for r in records if r.geometric is not None]
    scored = [g["acc_depth"] for g in geo if not g.get("excluded")]
    out["s_geo"] = float(np.mean(scored)) if scored else None
    out["n_geo_excluded"] = len(geo) - len(scored)
    out["n_no_depth"] = len(records) - len(geo)
    out["geo_notes"] = depth_checks.geo_notes(geo)  # views whose depth is doubtful (warned)
    fid = [r.fidelity for r in records if r.fidelity is not None]
    if fid:
        f = fidelity_summary(fid).to_dict()
        out.update(psnr=finite_or_none(f.get("psnr")), ssim=f.get("ssim"), lpips=f.get("lpips"), fidelity=f)
    else:
        out.update(psnr=None, ssim=None, lpips=None)
    out["n_views"] = len(scored) if scored else len([r for r in records if not _empty_target(r)])
    axes = [out.get("s_sem"), out.get("s_geo"), out.get("s_str")]
    out["rqs"] = None if any(a is None for a in axes) else float(rqs_of(*axes))
    if boundary:
        out["boundary"] = mean_boundary([b for b in boundary if b])
    return out


def per_view_axes(records, *, xis=XI_SWEEP) -> dict[str, dict]:
    """{view: `method_axes` of that view's record alone} for a method's per-view records
    (`ViewRecord` or their dicts), in their order."""
    out = {}
    for r in records:
        rec = ViewRecord.from_dict(r) if isinstance(r, dict) else r
        out[rec.view] = method_axes([rec], xis=xis)
    return out


def _empty_target(r: ViewRecord) -> bool:
    for v in list(r.semantic.values()) + list(r.structural.values()):
        return bool(v.empty_target)
    return bool(r.geometric and r.geometric.get("excluded"))


def mean_boundary(per_view: list[dict]) -> dict:
    """Average single-view boundary tables ({row: {label: value|None}}) over views.

    Each per-view value is already that view's contribution (a 0/1 detection,
    an IoU, acc_depth^v, sim^v or 1 - sim^v), and every row of the sweep is a
    mean over the scored views, so the mean of the non-None values is exact.
    """
    rows: dict = {}
    for table in per_view:
        for row, vals in table.items():
            acc = rows.setdefault(row, {})
            for label, v in vals.items():
                if v is not None:
                    acc.setdefault(label, []).append(v)
    labels = list(next(iter(per_view[0].values())).keys()) if per_view and per_view[0] else []
    return {row: {lab: (float(np.mean(acc[lab])) if acc.get(lab) else None) for lab in labels} for row, acc in rows.items()}


def common_methods(scenes: dict) -> tuple[list[str], dict[str, list[str]]]:
    """The methods every scene has (in order of first appearance) and, for each other method, the
    scenes it is missing from."""
    order: list[str] = []
    for s in scenes.values():
        order += [m for m in s["methods"] if m not in order]
    missing = {m: [name for name, s in scenes.items() if m not in s["methods"]] for m in order}
    return [m for m in order if not missing[m]], {m: v for m, v in missing.items() if v}


def axis_cells(scenes: dict) -> AxisCells | None:
    """AxisCells for aggregate_tables from ``results["scenes"]``, over the methods every scene has
    (:func:`common_methods`); None if no method is common or any axis is missing."""
    names = list(scenes)
    methods = common_methods(scenes)[0] if names else []
    if not methods:
        return None
    grids = {k: np.full((len(names), len(methods)), np.nan) for k in ("s_sem", "s_geo", "s_str", "n_views", "iou_drop")}
    for i, s in enumerate(names):
        ms = scenes[s]["methods"]
        for j, m in enumerate(methods):
            ax = ms[m]["axes"]
            for k in grids:
                v = ax.get(k)
                grids[k][i, j] = np.nan if v is None else float(v)
    if any(np.isnan(grids[k]).any() for k in AXES):
        return None
    n_views = grids["n_views"] if not np.isnan(grids["n_views"]).any() and (grids["n_views"] > 0).all() else None
    iou_drop = grids["iou_drop"] if not np.isnan(grids["iou_drop"]).any() else None
    return AxisCells(tuple(names), tuple(methods), grids["s_sem"], grids["s_geo"], grids["s_str"],
                     n_views=n_views, iou_drop=iou_drop)


def finite_or_none(x):
    """x when it is a finite number, else None (tagged non-finite values included)."""
    if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x):
        return float(x)
    return None
