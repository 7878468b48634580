"""All aggregate tables of a scenes x methods grid as one JSON-ready dict."""
from __future__ import annotations

import math

from ..protocol import CI_LEVEL, MIN_SCENES_TO_RANK, N_BOOT, N_PERM
from .association import axis_association
from .cells import AXES, AxisCells
from .ranks import rank_summary
from .reliability import reliability
from .rqs import pool_over_scenes, rqs

POOLING_VIEW_WEIGHTED = "view-weighted"
POOLING_SCENE_MACRO = "scene-macro"


def _num(x) -> float | None:
    """A JSON-safe float: NaN (undefined) becomes None."""
    x = float(x)
    return None if math.isnan(x) else x


def too_few_scenes(n_scenes: int) -> str:
    """Why the ranking's interval and P(beats best) are left out: fewer than MIN_SCENES_TO_RANK scenes."""
    return (f"too few scenes to rank with confidence ({n_scenes} scene{'s' if n_scenes != 1 else ''}; "
            f"at least {MIN_SCENES_TO_RANK} needed)")


def aggregate_tables(
    cells: AxisCells,
    n_boot: int = N_BOOT,
    n_perm: int = N_PERM,
    seed: int = 0,
    rank_decimals: int | None = None,
) -> dict:
    """Compute every aggregate table of the Remove360 protocol.

    Args:
        cells: the per-(scene, method) axis values.
        n_boot: bootstrap resamples for ``p_beats_best``.
        n_perm: within-scene permutations for ``p_centred``.
        seed: seed for both (each uses its own ``default_rng(seed)``).
        rank_decimals: round the overall axes to this many decimals before
            ranking (e.g. 3 = rank as printed); None ranks at full precision.

    Returns:
        A dict of plain Python values (str, float, int, None, dict, list) that
        serialises losslessly to JSON (no NaN: undefined values are None)::

            {"scenes": [SCENE, ...], "methods": [METHOD, ...],
             "rqs": {SCENE: {METHOD: float}},
             "overall_pooling": "view-weighted" | "scene-macro",
             "overall": {METHOD: {"s_sem", "s_geo", "s_str", "rqs"[, "iou_drop"]}},
             "scene_macro": {METHOD: {"s_sem", "s_geo", "s_str", "mean_rqs"[, "iou_drop"]}},
             "ranks": {METHOD: {"sem", "geo", "str", "avg_rank", "med_rank", "worst_rank"}},
             "reliability": {METHOD: {"mean", "sd", "min", "max", "ci_low", "ci_high",
                                      "p_beats_best": float | None}},
             "reliability_best": METHOD,
             "axis_association": {"sem-geo" | "sem-str" | "geo-str":
                                  {"rho", "rho_centred", "p_centred", "tau_mean", "tau_sd",
                                   "n_tau_scenes"}},
             "settings": {"n_boot", "n_perm", "seed", "ci_level", "min_scenes_to_rank", "rank_decimals"},
             "notes": {KEY: str}}

        ``overall`` pools over scenes view-weighted when ``cells.n_views`` is
        given (every view of every scene counts once), else it is the
        scene-macro mean; ``overall_pooling`` says which, and RQS is computed
        from the pooled axes.  ``scene_macro`` always weights scenes equally
        and its ``mean_rqs`` is the mean of the per-scene RQS (not the RQS of
        the mean axes).  ``reliability`` and ``reliability_best`` need at least
        ``MIN_SCENES_TO_RANK`` scenes and ``axis_association`` two; with fewer
        they are absent and ``notes`` says why (``notes["reliability"]``:
        "too few scenes to rank with confidence (N scenes; at least M needed)").
    """
    if n_boot < 1 or n_perm < 1:
        raise ValueError("n_boot and n_perm must be at least 1")
    scenes, methods = cells.scenes, cells.methods
    axes = cells.axes  # (S, M, 3)
    scene_rqs = rqs(axes[..., 0], axes[..., 1], axes[..., 2])  # (S, M)

    pooled = pool_over_scenes(axes, cells.n_views)  # (M, 3)
    pooled_rqs = rqs(pooled[:, 0], pooled[:, 1], pooled[:, 2])
    macro = pool_over_scenes(axes)
    macro_rqs = scene_rqs.mean(axis=0)
    pooled_drop = None if cells.iou_drop is None else pool_over_scenes(cells.iou_drop, cells.n_views)
    macro_drop = None if cells.iou_drop is None else pool_over_scenes(cells.iou_drop)

    out: dict = {
        "scenes": list(scenes),
        "methods": list(methods),
        "rqs": {s: {m: _num(scene_rqs[i, j]) for j, m in enumerate(methods)} for i, s in enumerate(scenes)},
        "overall_pooling": POOLING_SCENE_MACRO if cells.n_views is None else POOLING_VIEW_WEIGHTED,
        "overall": {},
        "scene_macro": {},
    }
    for j, m in enumerate(methods):
        row = {name: _num(pooled[j, k]) for k, name in enumerate(AXES)}
        row["rqs"] = _num(pooled_rqs[j])
        macro_row = {name: _num(macro[j, k]) for k, name in enumerate(AXES)}
        macro_row["mean_rqs"] = _num(macro_rqs[j])
        if pooled_drop is not None:
            row["iou_drop"] = _num(pooled_drop[j])
            macro_row["iou_drop"] = _num(macro_drop[j])
        out["overall"][m] = row
        out["scene_macro"][m] = macro_row

    ranks = rank_summary(pooled, decimals=rank_decimals)
    out["ranks"] = {
        m: {
            "sem": _num(ranks.ranks[j, 0]),
            "geo": _num(ranks.ranks[j, 1]),
            "str": _num(ranks.ranks[j, 2]),
            "avg_rank": _num(ranks.avg_rank[j]),
            "med_rank": _num(ranks.med_rank[j]),
            "worst_rank": _num(ranks.worst_rank[j]),
        }
        for j, m in enumerate(methods)
    }

    settings = {"n_boot": int(n_boot), "n_perm": int(n_perm), "seed": int(seed), "ci_level": CI_LEVEL,
                "min_scenes_to_rank": MIN_SCENES_TO_RANK, "rank_decimals": rank_decimals}
    notes: dict[str, str] = {}
    if len(scenes) >= MIN_SCENES_TO_RANK:
        rel = reliability(scene_rqs, n_boot=n_boot, seed=seed, ci_level=settings["ci_level"])
        out["reliability"] = {
            m: {
                "mean": _num(rel.mean[j]), "sd": _num(rel.sd[j]),
                "min": _num(rel.min[j]), "max": _num(rel.max[j]),
                "ci_low": _num(rel.ci_low[j]), "ci_high": _num(rel.ci_high[j]),
                "p_beats_best": _num(rel.p_beats_best[j]),
            }
            for j, m in enumerate(methods)
        }
        out["reliability_best"] = methods[rel.best]
    else:
        notes["reliability"] = too_few_scenes(len(scenes))
    if len(scenes) >= 2:
        out["axis_association"] = {
            pair: {
                "rho": _num(a.rho), "rho_centred": _num(a.rho_centred), "p_centred": _num(a.p_centred),
                "tau_mean": _num(a.tau_mean), "tau_sd": _num(a.tau_sd), "n_tau_scenes": a.n_tau_scenes,
            }
            for pair, a in axis_association(cells, n_perm=n_perm, seed=seed).items()
        }
    else:
        notes["axis_association"] = f"axis association omitted: needs at least two scenes; got {len(scenes)}"
    out["settings"] = settings
    out["notes"] = notes
    return out
