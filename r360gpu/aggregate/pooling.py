"""Cross-scene pooling of the results document: the aggregate tables and the
xi and boundary sweeps pooled over views like the Overall row."""
from __future__ import annotations

import numpy as np

from ..schema import Pooled
from .results import axis_cells, common_methods
from .summary import aggregate_tables


def wmean(pairs):
    """Weighted mean of (value, weight) pairs; the plain mean when no weight is positive."""
    w = sum(p[1] for p in pairs)
    if w <= 0:
        return float(np.mean([p[0] for p in pairs])) if pairs else None
    return float(sum(v * wt for v, wt in pairs) / w)


def pooled_sensitivity(scenes: dict, methods, scene_names) -> dict:
    """The xi sweep and the boundary sweep per method, each scene weighted by its n_views."""
    sens: dict = {"xi": {}, "boundary": {}}
    for m in methods:
        acc: dict = {}
        bnd: dict = {}
        for s in scene_names:
            ax = scenes[s]["methods"][m]["axes"]
            w = ax.get("n_views") or 0
            for k, v in (ax.get("acc_seg") or {}).items():
                if v is not None:
                    acc.setdefault(k, []).append((v, w))
            for row, vals in (ax.get("boundary") or {}).items():
                for lab, v in vals.items():
                    if v is not None:
                        bnd.setdefault(row, {}).setdefault(lab, []).append((v, w))
        sens["xi"][m] = {k: wmean(v) for k, v in acc.items()}
        sens["boundary"][m] = {row: {lab: wmean(v) for lab, v in labs.items()} for row, labs in bnd.items()}
    return sens


def aggregate_results(scenes: dict, *, n_boot: int, n_perm: int, seed: int) -> Pooled:
    """The run's cross-scene values from its scene entries (``scenes`` as results.json holds them):
    ``validity`` {axis: [scenes where the axis is "weak" or "blind"]}, the Overall cells to mark;
    ``aggregate`` and ``sensitivity``, or notes why not."""
    from .validity import not_ok_cells

    validity = not_ok_cells(scenes)
    cells = axis_cells(scenes)
    common, missing = common_methods(scenes)
    notes = []
    if missing:
        left = "; ".join(f"{m} (missing from {', '.join(s)})" for m, s in missing.items())
        notes.append(f"cross-scene tables use the methods every scene has ({', '.join(common) or 'none'}); "
                     f"left out: {left}")
    if cells is None:
        notes.append("aggregate tables need at least one method in every scene and all three axes")
        return Pooled(validity, None, None, notes, notes_first=bool(missing))
    return Pooled(validity, aggregate_tables(cells, n_boot=n_boot, n_perm=n_perm, seed=seed),
                  pooled_sensitivity(scenes, cells.methods, cells.scenes), notes, notes_first=bool(missing))
