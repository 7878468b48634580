"""Several probes on one axis: each probe's reading and the "most alarming" one.

A removal is only as good as the strongest evidence any probe still finds, so
besides each probe's own axis values we report, per view, the reading of the
probe that gives the *lowest oriented axis score* for that view (all axes are
oriented so that higher is better), and the axis over those worst readings.

* Semantic axis: the per-view score is ``1[IoU_post^v < ξ]``; the most
  alarming reading is the one with the **highest IoU_post** (any probe that
  still finds the object).  The maximum is the worst at every ξ at once, so
  one choice per view serves the whole threshold sweep.  The chosen view
  keeps that probe's IoU_pre too, so its iou_drop is the drop that probe
  measured.
* Structural axis, with a reference: per-view score sim^v; the most alarming
  reading is the **lowest sim^v**.  Reference-free: per-view score
  1 - sim^v; the most alarming reading is the **highest sim^v**.
* Geometric axis: it has no probe (one pair of depth renderings), so nothing
  is combined.

Ties go to the probe listed first.  The per-view readings of the probes are
lists aligned by view (same order, same length); the target-mask area of
each view must agree across probes, which catches misaligned lists.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from ..errors import InputError
from ..protocol import XI_DEFAULT
from .semantic import SemanticSummary, SemanticView, semantic_summary
from .structural import StructuralSummary, StructuralView, common_mode, structural_summary


@dataclass(frozen=True)
class SemanticCombined:
    """Semantic readings of several probes.

    per_probe: {probe: SemanticSummary}.
    worst: per view, the SemanticView with the highest IoU_post.
    worst_probe: per view, the name of the probe it came from.
    combined: SemanticSummary over ``worst``.
    """

    per_probe: dict[str, SemanticSummary]
    worst: list[SemanticView]
    worst_probe: list[str]
    combined: SemanticSummary

    def to_dict(self) -> dict:
        return {
            "per_probe": {k: v.to_dict() for k, v in self.per_probe.items()},
            "worst_probe": list(self.worst_probe),
            "combined": self.combined.to_dict(),
        }


@dataclass(frozen=True)
class StructuralCombined:
    """Structural readings of several probes (one mode).

    per_probe: {probe: StructuralSummary}.
    worst: per view, the StructuralView with the lowest oriented score s_str^v.
    worst_probe: per view, the probe it came from.
    combined: StructuralSummary over ``worst``.
    """

    mode: str
    per_probe: dict[str, StructuralSummary]
    worst: list[StructuralView]
    worst_probe: list[str]
    combined: StructuralSummary

    def to_dict(self) -> dict:
        return {
            "mode": self.mode,
            "per_probe": {k: v.to_dict() for k, v in self.per_probe.items()},
            "worst_probe": list(self.worst_probe),
            "combined": self.combined.to_dict(),
        }


def _check_aligned(views_by_probe: Mapping[str, Sequence], axis: str) -> tuple[list[str], int]:
    names = [str(k) for k in views_by_probe]
    if not names:
        raise InputError(f"{axis}: no probe readings to combine")
    lengths = {len(v) for v in views_by_probe.values()}
    if len(lengths) != 1:
        detail = ", ".join(f"{k}: {len(v)}" for k, v in views_by_probe.items())
        raise InputError(f"{axis}: probes cover different numbers of views ({detail})")
    n = lengths.pop()
    lists = list(views_by_probe.values())
    for i in range(n):
        areas = {lst[i].area_target for lst in lists}
        if len(areas) != 1:
            raise InputError(
                f"{axis}: view #{i} has different target-mask areas across probes {sorted(areas)}; "
                "the probes' view lists are not aligned"
            )
    return names, n


def _pick_worst(views_by_probe: Mapping[str, Sequence], key) -> tuple[list, list[str]]:
    """Per view, the reading minimising ``key`` (first probe on ties)."""
    names, n = _check_aligned(views_by_probe, "combine")
    lists = list(views_by_probe.values())
    worst, who = [], []
    for i in range(n):
        best = min(range(len(lists)), key=lambda p: (key(lists[p][i]), p))
        worst.append(lists[best][i])
        who.append(names[best])
    return worst, who


def most_alarming_semantic(
    views_by_probe: Mapping[str, Sequence[SemanticView]],
    xis: Iterable[float] = (XI_DEFAULT,),
    *,
    include_empty_targets: bool = False,
) -> SemanticCombined:
    """Each semantic probe's summary and the summary over the per-view maximum IoU_post."""
    _check_aligned(views_by_probe, "semantic axis")
    xis = tuple(xis)
    per = {
        str(k): semantic_summary(v, xis, include_empty_targets=include_empty_targets)
        for k, v in views_by_probe.items()
    }
    worst, who = _pick_worst(views_by_probe, lambda v: -v.iou_post)
    return SemanticCombined(per, worst, who, semantic_summary(worst, xis, include_empty_targets=include_empty_targets))


def most_alarming_structural(
    views_by_probe: Mapping[str, Sequence[StructuralView]],
    *,
    include_empty_targets: bool = False,
) -> StructuralCombined:
    """Each structural probe's summary and the summary over the per-view lowest s_str^v."""
    _check_aligned(views_by_probe, "structural axis")
    every = [v for lst in views_by_probe.values() for v in lst]
    if not every:
        raise InputError("structural axis: no views to combine")
    mode = common_mode(every)
    per = {
        str(k): structural_summary(v, mode=mode, include_empty_targets=include_empty_targets)
        for k, v in views_by_probe.items()
    }
    worst, who = _pick_worst(views_by_probe, lambda v: v.s_str)
    return StructuralCombined(
        mode, per, worst, who, structural_summary(worst, mode=mode, include_empty_targets=include_empty_targets)
    )
