"""Residuals on Gaussians (``score --residuals``): per splat method, the Gaussians behind the evidence.

Writes ``residuals/SCENE/METHOD.ply`` (the method's Gaussians with a
``residual`` property, :mod:`r360gpu.lift.residuals`) and records in the
scene's results entry, per method, the file, the flagged views and the
indices of the :data:`TOP` highest residuals.  Methods given as renderings
have no Gaussians: they are listed with a note.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

#: Indices of the highest residuals recorded per method.
TOP = 100


def scene_residuals(bundle, scene_res: dict, out, *, ctx=None, xis=(0.3,)) -> dict:
    """{method: {"file", "flagged_views", "top"} or {"note"}} for ``bundle`` scored as ``scene_res``."""
    from ..io import Gaussians, load_gaussians, load_mask
    from ..lift.residuals import flagged_views, residuals, top_residuals, write_residual_ply

    out_entry: dict = {}
    cams = [bundle.cameras[v] for v in bundle.views] if bundle.cameras else []
    for m, spec in bundle.methods.items():
        if not cams or not (isinstance(spec, Gaussians) or getattr(spec, "kind", None) == "scene"):
            out_entry[m] = {"note": "no residuals (renderings only)"}
            continue
        flagged = flagged_views(scene_res["methods"][m]["views"], xis=xis)
        g = spec if isinstance(spec, Gaussians) else load_gaussians(spec.path)
        masks = []
        for v, c in zip(bundle.views, cams):
            mk = bundle.masks[v]
            masks.append(np.asarray(mk) != 0 if isinstance(mk, np.ndarray)
                         else load_mask(mk, shape=(c.height, c.width)))
        r = residuals(g, cams, masks, flagged, ctx=ctx)
        write_residual_ply(Path(out) / "residuals" / bundle.name / f"{m}.ply", g, r)
        out_entry[m] = {"file": str(Path("residuals") / bundle.name / f"{m}.ply"), "flagged_views": flagged,
                        "top": top_residuals(r, TOP).tolist(), "max": float(r.max()) if len(r) else 0.0}
    return out_entry
