"""A small, fully specified results document for the report tests (no GPU).

2 scenes x 3 methods x 3 views, built from real per-view measurement objects
(SemanticView, StructuralView, GeometricView, FidelityView -> ViewRecord), the
real summaries and the real aggregation, with contact sheets and per-view
plots written by the report's own picture functions.

Per-view values (view index v = 0, 1, 2):

* IoU_pre = 0.85 + 0.02 v for every method;
* IoU_post: clean 0.05; blurry 0.2 + 0.1 v (detected at 0.3 on v = 1, 2); ghost 0.1;
* acc_depth: clean 0.9 - 0.05 v; blurry 0.7 (garden: 0.95); ghost 0.2 + 0.05 v;
* sim_SAM: clean 0.8, blurry 0.5, ghost 0.6 (reference mode: s_str = sim_SAM);
* PSNR / SSIM / LPIPS: clean 25 + v / 0.8 / 0.2, blurry 20 / 0.6 / 0.4,
  ghost 22 / 0.7 / 0.3; except room/clean/view 01, identical to the
  reference (PSNR = +inf, stored tagged);
* garden view "02" has an empty target mask: excluded from every axis.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from r360gpu.aggregate import AxisCells, aggregate_tables
from r360gpu.metrics.fidelity import FidelityView, fidelity_summary
from r360gpu.metrics.geometric import GeometricView
from r360gpu.metrics.record import ViewRecord
from r360gpu.metrics.semantic import XI_SWEEP, SemanticView, semantic_summary
from r360gpu.metrics.structural import StructuralView, structural_summary
from r360gpu.report.contact_sheets import view_contact_sheet
from r360gpu.report.plots import view_axes_plot
from r360gpu.report.results_io import RESULTS_SCHEMA

SCENES = ("room", "garden")
METHODS = ("clean", "blurry", "ghost")
VIEWS = ("00", "01", "02")
SEM_PROBE = "builtin-appearance"
STR_PROBE = "builtin-graphseg"
H, W = 48, 64
PROBES = {
    "semantic": [{"name": SEM_PROBE, "kind": "semantic", "models": {}, "params": {"blur": 1.5},
                  "weight_free": True, "limitations": "colour statistics only"}],
    "structural": [{"name": STR_PROBE, "kind": "structural", "models": {}, "params": {"k": 300},
                    "weight_free": True, "limitations": "graph segmentation"}],
}
LPIPS_MODEL = {"file": "lpips_alex.onnx", "sha256": "ab" * 32, "inputs": ["a", "b"], "output": "d"}


def iou_post(method: str, v: int) -> float:
    return {"clean": 0.05, "blurry": 0.2 + 0.1 * v, "ghost": 0.1}[method]


def acc_depth(scene: str, method: str, v: int) -> float:
    if method == "clean":
        return 0.9 - 0.05 * v
    if method == "blurry":
        return 0.95 if scene == "garden" else 0.7
    return 0.2 + 0.05 * v


SIM = {"clean": 0.8, "blurry": 0.5, "ghost": 0.6}
FID = {"clean": (25.0, 0.8, 0.2), "blurry": (20.0, 0.6, 0.4), "ghost": (22.0, 0.7, 0.3)}


def empty(scene: str, view: str) -> bool:
    return scene == "garden" and view == "02"


def target_mask(scene: str, view: str) -> np.ndarray:
    m = np.zeros((H, W), bool)
    if not empty(scene, view):
        v = VIEWS.index(view)
        m[14:34, 18 + 4 * v : 44 + 4 * v] = True
    return m


def images(scene: str, method: str, view: str):
    """(pre, post, ref, d_pre, d_post, target) float arrays for the pictures."""
    rng = np.random.default_rng(SCENES.index(scene) * 100 + METHODS.index(method) * 10 + VIEWS.index(view))
    t = target_mask(scene, view)
    yy, xx = np.mgrid[0:H, 0:W]
    bg = np.stack([0.3 + 0.4 * xx / W, 0.5 + 0.2 * yy / H, np.full((H, W), 0.6)], axis=2)
    bg = np.clip(bg + rng.normal(0, 0.02, bg.shape), 0, 1).astype(np.float32)
    pre = bg.copy()
    pre[t] = (0.9, 0.15, 0.1)
    post = bg.copy()
    if method == "ghost":
        post[t] = 0.5 * bg[t] + 0.5 * np.array((0.9, 0.15, 0.1), np.float32)
    if method == "blurry":
        post[t] = 0.7 * bg[t] + 0.3 * np.array((0.9, 0.15, 0.1), np.float32)
    d_plane = (2.0 + yy / H).astype(np.float32)
    d_pre = d_plane.copy()
    d_pre[t] = 1.2
    d_post = d_plane.copy()
    if method == "ghost":
        d_post[t] = 1.25
    return pre, post, bg, d_pre, d_post, t


def no_depth(scene: str, method: str, view: str) -> int:
    """Pixels of M with no depth after removal: ghost leaves a see-through hole in the room's views."""
    if scene != "room" or method != "ghost" or empty(scene, view):
        return 0
    return 7 * (VIEWS.index(view) + 1)


def view_record(scene: str, method: str, view: str) -> ViewRecord:
    v = VIEWS.index(view)
    ex = empty(scene, view)
    area = int(target_mask(scene, view).sum())
    sem = SemanticView(
        iou_pre=0.0 if ex else 0.85 + 0.02 * v, iou_post=0.0 if ex else iou_post(method, v), empty_target=ex,
        area_target=area, area_pred_pre=400, area_pred_post=30, inter_pre=0 if ex else 380,
        inter_post=0 if ex else 20, n_instances_pre=1, n_instances_post=1, probe=SEM_PROBE)
    st = StructuralView(
        sim_sam=1.0 if ex else SIM[method], n_a=0 if ex else 2, n_b=0 if ex else 2,
        retained_a=() if ex else (0, 1), retained_b=() if ex else (0, 2),
        pairs=() if ex else ((0, 0), (1, 2)), pair_iou=() if ex else (SIM[method], SIM[method]),
        empty_target=ex, area_target=area, mode="reference", probe=STR_PROBE)
    acc = None if ex else acc_depth(scene, method, v)
    n_in = 0 if ex else int(round(acc * area))
    geo = GeometricView(acc_depth=acc, excluded=ex, threshold=0.25 + 0.01 * v, split=60.0 + v, lo=0.0, hi=1.0,
                        hist=np.zeros(256, np.int64), changed=np.zeros((H, W), bool), n_mask=area,
                        n_changed_in_mask=n_in, mode="float", n_no_depth_in_mask=no_depth(scene, method, view))
    ps, ss, lp = FID[method]
    identical = scene == "room" and method == "clean" and view == "01"
    psnr = math.inf if identical else ps + (v if method == "clean" else 0)
    fid = FidelityView(mse=0.0 if math.isinf(psnr) else 10 ** (-psnr / 10), psnr=psnr, ssim=ss, lpips=lp,
                       lpips_reason=None, lpips_model=LPIPS_MODEL)
    return ViewRecord.build(view, scene, method, probes=PROBES["semantic"] + PROBES["structural"],
                            semantic=[sem], structural=[st], geometric=geo, fidelity=fid)


def method_axes(records: list[ViewRecord]) -> dict:
    sems = [r.semantic[SEM_PROBE] for r in records]
    strs = [r.structural[STR_PROBE] for r in records]
    ss = semantic_summary(sems, XI_SWEEP)
    st = structural_summary(strs)
    geo = [r.geometric["acc_depth"] for r in records if not r.geometric["excluded"]]
    s_geo = float(np.mean(geo))
    fs = fidelity_summary([r.fidelity for r in records])
    return {
        "s_sem": ss.s_sem, "s_geo": s_geo, "s_str": st.s_str,
        "rqs": float(np.cbrt(ss.s_sem * s_geo * st.s_str)),
        "iou_pre": ss.iou_pre, "iou_post": ss.iou_post, "iou_drop": ss.iou_drop,
        "acc_seg": {repr(x): v for x, v in ss.acc_seg.items()},
        "n_geo_excluded": len(records) - len(geo),
        "psnr": fs.psnr, "ssim": fs.ssim, "lpips": fs.lpips,
        "by_probe": {"semantic": {SEM_PROBE: ss.to_dict()}, "structural": {STR_PROBE: st.to_dict()}},
        "most_alarming": {"semantic": SEM_PROBE, "structural": STR_PROBE},
    }


def fake_results(out_dir: Path | None = None, *, methods=METHODS, pictures: bool = True) -> dict:
    """The results document; with ``out_dir`` and ``pictures`` the contact sheets and
    plots are written under it and referenced by relative paths."""
    scenes: dict = {}
    s_sem, s_geo, s_str, drops = [], [], [], []
    for scene in SCENES:
        mdict = {}
        rows = ([], [], [], [])
        for method in methods:
            recs = [view_record(scene, method if method in METHODS else "ghost", v) for v in VIEWS]
            recs = [ViewRecord.build(r.view, r.scene, method, probes=r.probes, semantic=r.semantic,
                                     structural=r.structural, geometric=r.geometric, fidelity=r.fidelity)
                    for r in recs]
            axes = method_axes(recs)
            entry = {"axes": axes, "views": [r.to_dict() for r in recs]}
            if out_dir is not None and pictures:
                pics = {}
                for view in VIEWS:
                    pre, post, ref, d_pre, d_post, t = images(scene, method if method in METHODS else "ghost", view)
                    rel = f"pictures/{scene}/{method}/{view}.png"
                    delta = np.abs(d_pre - d_post)
                    sem_mask = np.zeros((H, W), bool)
                    sem_mask[16:30, 20:40] = method != "clean"
                    struct = np.stack([t, np.roll(t, 5, axis=1) & ~t])
                    view_contact_sheet(out_dir / rel, pre=pre, post=post, ref=ref, target=t, delta=delta,
                                       threshold=0.25, semantic_post=sem_mask,
                                       structural=[("structural masks on I_post", post, struct)],
                                       width=128, title=f"{scene} / {method} / {view}",
                                       record=recs[VIEWS.index(view)].to_dict())
                    pics[view] = rel
                plot = f"plots/{scene}/{method}.png"
                view_axes_plot(out_dir / plot, recs, title=f"{scene} / {method}")
                entry["pictures"] = pics
                entry["plot"] = plot
            mdict[method] = entry
            for lst, k in zip(rows, ("s_sem", "s_geo", "s_str", "iou_drop")):
                lst.append(axes[k])
        for lst, r in zip((s_sem, s_geo, s_str, drops), rows):
            lst.append(r)
        scenes[scene] = {"prompt": "red box", "n_views": len(VIEWS), "views": list(VIEWS), "reference": True,
                         "excluded_views": {"empty_target": ["02"]} if scene == "garden" else {},
                         "methods": mdict}
    cells = AxisCells(SCENES, tuple(methods), np.array(s_sem), np.array(s_geo), np.array(s_str),
                      n_views=np.full((len(SCENES), len(methods)), float(len(VIEWS))), iou_drop=np.array(drops))
    agg = aggregate_tables(cells, n_boot=200, n_perm=50)
    xi = {}
    boundary = {}
    for j, m in enumerate(methods):
        xi[m] = {repr(x): float(np.mean([scenes[s]["methods"][m]["axes"]["acc_seg"][repr(x)] for s in SCENES]))
                 for x in XI_SWEEP}
        base = agg["overall"][m]
        boundary[m] = {
            "iou_drop": {lab: base["iou_drop"] + d for lab, d in
                         zip(("E15", "E10", "E5", "Original", "D5", "D10", "D15"),
                             (0.03, 0.02, 0.01, 0.0, -0.04, -0.08, -0.12))},
            "acc_depth": {lab: base["s_geo"] + d for lab, d in
                          zip(("E15", "E10", "E5", "Original", "D5", "D10", "D15"),
                              (0.02, 0.01, 0.005, 0.0, -0.01, -0.02, -0.03))},
        }
    return {
        "schema": RESULTS_SCHEMA,
        "r360gpu_version": "0.1.0",
        "created": "2025-01-01T00:00:00Z",
        "adapter": {"name": "llvmpipe", "backend": "Vulkan", "features": ["timestamp-query"]},
        "options": {"background": [0.0, 0.0, 0.0], "depth": "expected", "reference_free": False},
        "probes": PROBES,
        "scenes": scenes,
        "aggregate": agg,
        "sensitivity": {"xi": xi, "boundary": boundary},
    }


def add_probe_checks(results: dict) -> dict:
    """Fabricated probe verdicts and control scores, the way the probe-validity step stores them:
    room: s_geo weak; garden: s_sem blind; the others ok."""
    verdicts = {"room": {"s_sem": "ok", "s_geo": "weak", "s_str": "ok"},
                "garden": {"s_sem": "blind", "s_geo": "ok", "s_str": "ok"}}
    for s in SCENES:
        sd = results["scenes"][s]
        sd["validity"] = dict(verdicts[s])
        sd["controls"] = {
            "identity": {"axes": {"s_sem": 0.9 if s == "garden" else 0.1, "s_geo": 0.3 if s == "room" else 0.02,
                                  "s_str": 0.2, "rqs": 0.1}},
            "reference": {"axes": {"s_sem": 1.0, "s_geo": 0.45 if s == "room" else 0.95, "s_str": 0.97,
                                   "rqs": 0.7}},
        }
    return results


def add_expected(results: dict) -> dict:
    """Fabricated known failures (scene.toml [expected.METHOD]) for the three fake methods."""
    for s in SCENES:
        results["scenes"][s]["expected"] = {
            "clean": {"failure": "none", "caught_by": []},
            "blurry": {"failure": "a faint copy of the object stays", "caught_by": ["s_sem"]},
            "ghost": {"failure": "half-transparent object at its old depth", "caught_by": ["s_geo", "s_str"]},
        }
    return results


def add_ranked_reliability(results: dict, n_scenes: int = 6) -> dict:
    """The "how sure is the ranking" statistics of a grid with enough scenes to state them (the fake's
    two scenes are too few): the fake's methods over ``n_scenes`` seeded random scenes."""
    methods = tuple(results["aggregate"]["methods"])
    rng = np.random.default_rng(n_scenes)
    cells = AxisCells(tuple(f"s{i}" for i in range(n_scenes)), methods,
                      *(rng.random((n_scenes, len(methods))) for _ in range(3)))
    ranked = aggregate_tables(cells, n_boot=200, n_perm=50)
    agg = results["aggregate"]
    agg["reliability"], agg["reliability_best"] = ranked["reliability"], ranked["reliability_best"]
    agg["notes"].pop("reliability", None)
    return results
