"""Can an axis of a scene be trusted?  A verdict per axis from the controls and the pre-removal detectability.

The paper warns that a low post-removal response is hard to read when the
probe did not find the target before removal, and advises acting on the most
alarming of several probes.  The controls (:mod:`r360gpu.pipeline.stages`)
make this measurable per scene:

* the **identity control** scores the unedited pre-removal scene as if it
  were a method.  Nothing was removed, so a trustworthy axis gives it a low
  score; an axis on which it scores above :data:`BLIND_ABOVE` cannot tell an
  untouched scene from a removal and is **blind** there;
* the **reference control** scores the reconstruction of the physical
  post-removal capture, a real removal: an axis on which it scores below
  :data:`REFERENCE_BELOW` does not recognise a real removal (reported as
  **weak**; it errs on the alarming side);
* the semantic probe's pre-removal detectability: scene mIoU_pre and the
  fraction of views with IoU_pre >= xi (the best semantic probe per view).

Verdicts, per axis (``s_sem``, ``s_geo``, ``s_str``):

=========  ===================================================================
"blind"    identity control > 0.5; or, without controls, the target found
           (IoU_pre >= xi) in fewer than half of the views (s_sem only: the
           identity control's s_sem is exactly that fraction's complement)
"weak"     identity control > 0.2; reference control < 0.5; or (s_sem)
           mIoU_pre < 0.5 or the target found in fewer than 80% of the views
"ok"       none of these
None       the axis was not computed for this scene
=========  ===================================================================
"""
from __future__ import annotations

import numpy as np

from ..protocol import AXES, XI_DEFAULT

AXIS_NAMES = {"s_sem": "semantic", "s_geo": "geometric", "s_str": "structural"}
BLIND_ABOVE = 0.5
WEAK_ABOVE = 0.2
REFERENCE_BELOW = 0.5
MIOU_PRE_WEAK = 0.5
DETECT_WEAK = 0.8


def detectability(view_records: list[dict], xi: float = XI_DEFAULT) -> dict | None:
    """Scene mIoU_pre and the fraction of views with IoU_pre >= xi, over the views
    with a non-empty target; per view the best semantic probe counts.

    view_records: per-view records as stored (``ViewRecord.to_dict()``).
    Returns {"miou_pre", "detect_frac", "n_views", "xi"} or None without semantic readings.
    """
    best = []
    for r in view_records:
        sem = [s for s in (r.get("semantic") or {}).values() if not s.get("empty_target")]
        if sem:
            best.append(max(float(s["iou_pre"]) for s in sem))
    if not best:
        return None
    a = np.asarray(best)
    return {"miou_pre": float(a.mean()), "detect_frac": float((a >= xi).mean()), "n_views": int(a.size), "xi": xi}


def scene_validity(scene: dict, xi: float = XI_DEFAULT) -> tuple[dict, dict, dict | None]:
    """({axis: "ok" | "weak" | "blind" | None}, {axis: one sentence per non-ok verdict},
    :func:`detectability`) of one scene.

    scene: the scene's results entry (``methods``, optional ``controls``).
    """
    controls = scene.get("controls") or {}
    ident = (controls.get("identity") or {}).get("axes") or {}
    ref = (controls.get("reference") or {}).get("axes") or {}
    records = (controls.get("identity") or {}).get("views")
    if records is None:  # no controls: the methods' own pre readings
        records = [r for m in scene.get("methods", {}).values() for r in m.get("views", [])]
    det = detectability(records, xi)
    computed = {a: any((m.get("axes") or {}).get(a) is not None for m in scene.get("methods", {}).values())
                for a in AXES}
    verdicts: dict = {}
    notes: dict = {}
    for a in AXES:
        if not computed[a]:
            verdicts[a] = None
            continue
        name = AXIS_NAMES[a]
        reasons_blind, reasons_weak = [], []
        vi, vr = ident.get(a), ref.get(a)
        if vi is not None and vi > BLIND_ABOVE:
            reasons_blind.append(f"the unedited scene (identity control) scores {a} = {vi:.3f} > {BLIND_ABOVE}, "
                                 f"so a high {a} does not show that anything was removed")
        elif vi is not None and vi > WEAK_ABOVE:
            reasons_weak.append(f"the unedited scene (identity control) already scores {a} = {vi:.3f}")
        if vr is not None and vr < REFERENCE_BELOW:
            reasons_weak.append(f"the real removal (reference control) scores only {a} = {vr:.3f}, "
                                f"so the {name} axis may miss real removals")
        if a == "s_sem" and det is not None:
            found = f"the semantic probe finds the target before removal in {det['detect_frac']:.0%} of " \
                    f"{det['n_views']} views (IoU_pre >= {xi:g}; mIoU_pre {det['miou_pre']:.3f})"
            if vi is None and det["detect_frac"] < 1.0 - BLIND_ABOVE:
                reasons_blind.append(found + ", so most 'not detected' views say nothing about the removal")
            elif det["detect_frac"] < DETECT_WEAK or det["miou_pre"] < MIOU_PRE_WEAK:
                if not reasons_blind:
                    reasons_weak.append(found)
        if reasons_blind:
            verdicts[a], notes[a] = "blind", f"{name} axis blind: " + "; ".join(reasons_blind) + "."
        elif reasons_weak:
            verdicts[a], notes[a] = "weak", f"{name} axis weak: " + "; ".join(reasons_weak) + "."
        else:
            verdicts[a] = "ok"
    return verdicts, notes, det


def not_ok_cells(scenes: dict) -> dict:
    """{axis: [scenes where its verdict is "weak" or "blind"]}: the Overall cells to mark."""
    out: dict = {a: [] for a in AXES}
    for s, sc in scenes.items():
        for a, v in (sc.get("validity") or {}).items():
            if v in ("weak", "blind"):
                out.setdefault(a, []).append(s)
    return out
