"""The ``--compat`` modes at the scene level: the public scripts' numbers as the scene axes.

:func:`scene_compat` is called by the scoring pipeline where it measures a scene
(:func:`r360gpu.pipeline.schedule.evaluate_scene`), beside the scene's own axes
(:func:`r360gpu.aggregate.results.method_axes`), when a compat mode is on.  For a
bundle read from a public Remove360 folder (``layout == "remove360"``) it scores the
folder as the public scripts do
(:func:`r360gpu.metrics.compat_public.evaluate_public_folder`: their inputs, decoders,
view lists and summaries); the scene entry is then built with

* the method's scene axes (``s_sem``, ``acc_seg``, ``iou_pre``, ``iou_post``,
  ``iou_drop``, ``s_geo``, ``s_str``, ``sim_sam``, ``rqs``) taken from the scripts
  (:meth:`SceneCompat.axes`), r360gpu's own kept under ``axes.compat.replaced``;
* ``compat`` in each per-view record (:meth:`SceneCompat.view`): that view's values in
  each script (None where the script has no such view, e.g. a view whose SAM masks the
  script does not report);
* the scripts' per-axis view lists and counts under ``axes.compat``.

Why at the scene and not per view: the scripts' scene values are means over their own
view lists (every ``masks/*.png``; every depth pair, with or without a mask; the views
with SAM JSON on both sides), which are not the pipeline's evaluation views (``--views``
does not narrow them either), so no per-view stage sees all the views they average.

For any other bundle only the per-view geometric rule changes (applied in
:func:`r360gpu.metrics.geometric.acc_depth_view` to the depth the bundle gives); a note
saying that parity with the scripts is claimed for public folders only is added.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..metrics.compat import check_compat
from ..metrics.compat_public import evaluate_public_folder
from ..metrics.geometric import GhtParams
from ..protocol import XI_PUBLIC
from .rqs import rqs as rqs_of

REPLACED = ("s_sem", "acc_seg", "iou_pre", "iou_post", "iou_drop", "s_geo", "s_str", "sim_sam", "rqs", "n_views")
#: The scene note of a compat mode on a bundle that is not a public Remove360 folder.
NOT_PUBLIC_NOTE = ("compat mode {mode!r}: the public scripts' depth rule and 8-bit threshold are applied to this "
                   "bundle's depth; the semantic and structural axes are r360gpu's. Parity with the public scripts "
                   "is claimed (and tested) for public Remove360 folders only.")
#: The per-view values kept for each script, by the scripts' axis names.
SCRIPT_AXES = ("semantic", "geometric", "structural")


@dataclass
class SceneCompat:
    """One scene's compat mode: its scene notes and, for a public folder, the scripts' values.

    public: :func:`~r360gpu.metrics.compat_public.evaluate_public_folder`'s result (None:
    not a public folder, the axes stay r360gpu's).
    """

    mode: str
    notes: list
    public: dict | None = None

    def axes(self, own: dict) -> dict:
        """A method's scene axes in this mode, from r360gpu's own (``own`` is not changed)."""
        if self.public is None:
            return own
        sc = self.public["scene"]
        axes = dict(own)
        replaced = {k: own.get(k) for k in REPLACED}
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
            "mode": self.mode,
            "source": "public Remove360 folder scored as simonakocour/anything_left dd0aad8 does",
            "n_views": sc["n_views"],
            "views": {axis: sorted(v) for axis, v in self.public["views"].items()},
            "replaced": replaced,
        }
        return axes

    def view(self, record: dict) -> dict:
        """A per-view record (a dict) in this mode: with the scripts' values of its view under ``compat``."""
        if self.public is None:
            return record
        v = record["view"]
        return {**record, "compat": {axis: self.public["views"][axis].get(v) for axis in SCRIPT_AXES}}


def scene_compat(bundle, methods: list, compat, *, xis=XI_PUBLIC, ght=None) -> SceneCompat | None:
    """The compat mode of one scene (None: paper mode); a public folder is scored as the scripts
    score it (see the module doc).  methods: the scene's methods (a public folder holds one)."""
    mode = check_compat(compat)
    if mode is None:
        return None
    if getattr(bundle, "layout", None) != "remove360":
        return SceneCompat(mode, [NOT_PUBLIC_NOTE.format(mode=mode)])
    if len(methods) != 1:  # a public folder holds exactly one method (rgb/after)
        raise ValueError(f"a public Remove360 folder has one method, got {list(methods)}")
    ght = ght if isinstance(ght, GhtParams) else GhtParams(**(ght or {}))
    res = evaluate_public_folder(bundle.root, mode, xis=xis, ght=ght)
    return SceneCompat(mode, list(res["notes"]), res)
