"""The ``--compat`` modes in a results document: the public scripts' numbers as the scene axes.

:func:`apply_compat` is called by the scoring pipeline once per scene when a
compat mode is on.  For a bundle read from a public Remove360 folder
(``layout == "remove360"``) it scores the folder as the public scripts do
(:func:`r360gpu.metrics.compat_public.evaluate_public_folder`: their inputs,
decoders, view lists and summaries) and

* replaces the method's scene axes (``s_sem``, ``acc_seg``, ``iou_pre``,
  ``iou_post``, ``iou_drop``, ``s_geo``, ``s_str``, ``sim_sam``, ``rqs``)
  with the scripts' values, keeping r360gpu's own under
  ``axes.compat.replaced``;
* adds ``compat`` to each per-view record: that view's values in each script
  (None where the script has no such view, e.g. a view whose SAM masks the
  script does not report);
* records the scripts' per-axis view lists and counts under ``axes.compat``.

For any other bundle only the per-view geometric rule changes (applied in
:func:`r360gpu.metrics.geometric.acc_depth_view` to the depth the bundle
gives); a note saying that parity with the scripts is claimed for public
folders only is added.
"""
from __future__ import annotations

from ..metrics.compat import check_compat
from ..metrics.compat_public import evaluate_public_folder
from ..metrics.geometric import GhtParams
from ..protocol import XI_PUBLIC
from .rqs import rqs as rqs_of

REPLACED = ("s_sem", "acc_seg", "iou_pre", "iou_post", "iou_drop", "s_geo", "s_str", "sim_sam", "rqs", "n_views")


def apply_compat(scene: dict, bundle, compat, *, xis=XI_PUBLIC, ght=None) -> None:
    """Put the public scripts' values into one scene's results (in place); see the module doc."""
    mode = check_compat(compat)
    if mode is None:
        return
    notes = scene.setdefault("notes", [])
    if getattr(bundle, "layout", None) != "remove360":
        notes.append(f"compat mode {mode!r}: the public scripts' depth rule and 8-bit threshold are applied to "
                     "this bundle's depth; the semantic and structural axes are r360gpu's. Parity with the "
                     "public scripts is claimed (and tested) for public Remove360 folders only.")
        return
    methods = list(scene["methods"])
    if len(methods) != 1:  # a public folder holds exactly one method (rgb/after)
        raise ValueError(f"a public Remove360 folder has one method, got {methods}")
    res = evaluate_public_folder(bundle.root, mode, xis=xis, ght=ght if isinstance(ght, GhtParams) else GhtParams(**(ght or {})))
    notes.extend(res["notes"])
    cell = scene["methods"][methods[0]]
    axes = cell["axes"]
    sc = res["scene"]
    replaced = {k: axes.get(k) for k in REPLACED}
    axes.update(
        s_sem=sc["s_sem"], acc_seg=sc["acc_seg"], iou_pre=sc["iou_pre"], iou_post=sc["iou_post"],
        iou_drop=sc["iou_drop"], s_geo=sc["s_geo"], s_str=sc["s_str"], sim_sam=sc["sim_sam"],
        n_views=sc["n_views"]["semantic"],
    )
    parts = [axes["s_sem"], axes["s_geo"], axes["s_str"]]
    axes["rqs"] = None if any(a is None for a in parts) else float(rqs_of(*parts))
    # The pipeline read no depth (bundle.remove360_layout.without_depth); the scripts exclude no view.
    axes["n_no_depth"] = 0
    axes["n_geo_excluded"] = 0
    axes["compat"] = {
        "mode": mode,
        "source": "public Remove360 folder scored as simonakocour/anything_left dd0aad8 does",
        "n_views": sc["n_views"],
        "views": {axis: sorted(v) for axis, v in res["views"].items()},
        "replaced": replaced,
    }
    for rec in cell["views"]:
        v = rec["view"]
        rec["compat"] = {axis: res["views"][axis].get(v) for axis in ("semantic", "geometric", "structural")}
