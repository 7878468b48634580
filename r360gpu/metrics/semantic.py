"""Semantic axis: IoU_drop and acc_seg (paper eq. gsam_iou, eq. acc_seg; docs/protocol.md).

Per view ``v`` the semantic probe's instances on I_pre and on I_post are merged
into one predicted mask each (the union of the instances; no instance -> an
empty mask) and compared with the target mask M^v:

* ``IoU_pre^v = IoU(M̂_pre^v, M^v)``, ``IoU_post^v = IoU(M̂_post^v, M^v)``, with
  ``IoU = |A ∩ B| / |A ∪ B|`` and IoU = 0 when the union is empty;
* ``iou_drop^v = IoU_pre^v - IoU_post^v`` (in [-1, 1]);
* the object counts as *detected at ξ* on I_post when ``IoU_post^v >= ξ``.

Over views: mean IoU_pre, mean IoU_post, ``iou_drop`` (the mean of the
per-view drops) and ``acc_seg,ξ`` = fraction of views with ``IoU_post^v < ξ``
for any list of thresholds; ``s_sem = acc_seg,0.3``.

Empty target mask.  The paper does not say what an empty M^v means for this
axis.  The public reference code (github.com/simonakocour/anything_left,
``remove360/evaluation/semantic.py``) scores such a view: its
``calculate_iou`` returns 0 for an empty M (intersection 0), so IoU_pre =
IoU_post = 0, iou_drop = 0 and the view counts as "not detected", i.e. as a
success for acc_seg; it only skips views whose mask *file* is missing.
Here the per-view values are the same (both IoUs 0, flagged
``empty_target``), but by default the view is **excluded** from the means and
reported in ``n_empty_target``, as the geometric axis does for the same view:
an empty target gives no evidence of suppression and must not be scored 1.
``include_empty_targets=True`` reproduces the reference behaviour.

All IoUs are computed by the GPU mask kernels (:mod:`r360gpu.kernels.mask_iou`).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..kernels import mask_iou as K
from ..protocol import XI_DEFAULT, XI_SWEEP
from . import json_values
from ._masks import mask_stack, probe_name, target_mask



@dataclass(frozen=True)
class SemanticView:
    """Semantic measurement of one view by one probe.

    iou_pre, iou_post: IoU(M̂_pre, M), IoU(M̂_post, M) in [0, 1].
    empty_target: M^v has no pixel (both IoUs are then 0).
    area_target, area_pred_pre, area_pred_post: pixel counts of M^v and of the
        two predicted (union) masks.
    inter_pre, inter_post: pixel counts of M̂_pre ∩ M and M̂_post ∩ M.
    n_instances_pre, n_instances_post: number of instances the probe returned.
    probe: name of the semantic probe.
    """

    iou_pre: float
    iou_post: float
    empty_target: bool
    area_target: int
    area_pred_pre: int
    area_pred_post: int
    inter_pre: int
    inter_post: int
    n_instances_pre: int
    n_instances_post: int
    probe: str = ""

    @property
    def iou_drop(self) -> float:
        """IoU_pre - IoU_post, in [-1, 1]."""
        return self.iou_pre - self.iou_post

    def detected(self, xi: float = XI_DEFAULT) -> bool:
        """Whether the probe still finds the object on I_post at threshold ξ (IoU_post >= ξ)."""
        return self.iou_post >= check_xi(xi)

    def detected_at(self, xis: Iterable[float] = XI_SWEEP) -> dict[float, bool]:
        """{ξ: detected(ξ)} for every threshold of ``xis``."""
        return {float(x): self.detected(x) for x in xis}

    def to_dict(self) -> dict:
        """JSON-ready dict.  ``iou_drop`` and ``detected`` (at :data:`XI_SWEEP`,
        keys ``repr(ξ)``) are derived values written for readers;
        :meth:`from_dict` recomputes them."""
        return {
            "probe": self.probe,
            "iou_pre": self.iou_pre,
            "iou_post": self.iou_post,
            "iou_drop": self.iou_drop,
            "detected": {json_values.xi_key(x): v for x, v in self.detected_at().items()},
            "empty_target": self.empty_target,
            "area_target": self.area_target,
            "area_pred_pre": self.area_pred_pre,
            "area_pred_post": self.area_pred_post,
            "inter_pre": self.inter_pre,
            "inter_post": self.inter_post,
            "n_instances_pre": self.n_instances_pre,
            "n_instances_post": self.n_instances_post,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "SemanticView":
        what = "semantic view record"
        f = lambda k: json_values.field(d, k, what)  # noqa: E731
        return cls(
            iou_pre=float(f("iou_pre")),
            iou_post=float(f("iou_post")),
            empty_target=bool(f("empty_target")),
            area_target=int(f("area_target")),
            area_pred_pre=int(f("area_pred_pre")),
            area_pred_post=int(f("area_pred_post")),
            inter_pre=int(f("inter_pre")),
            inter_post=int(f("inter_post")),
            n_instances_pre=int(f("n_instances_pre")),
            n_instances_post=int(f("n_instances_post")),
            probe=str(d.get("probe", "")),
        )


def check_xi(xi: float) -> float:
    """ξ as a float in [0, 1], else InputError."""
    x = float(xi)
    if not (0.0 <= x <= 1.0):
        raise InputError(f"IoU threshold ξ must lie in [0, 1], got {xi!r}")
    return x


def _predicted_union(stack: np.ndarray, ctx) -> np.ndarray:
    """bool (H, W) union of an instance stack (GPU for K > 1)."""
    if stack.shape[0] == 1:
        return stack[0]
    return K.union(stack, ctx=ctx)


def semantic_view_from_unions(
    preds,
    target,
    *,
    n_instances: tuple[int, int],
    probe: str = "",
    ctx=None,
) -> SemanticView:
    """SemanticView from the two predicted (union) masks.

    preds: bool (2, H, W) stack [M̂_pre, M̂_post], or that stack already
        uploaded with :func:`r360gpu.kernels.mask_iou.pack` (to reuse it
        across several targets, as the boundary sweep does).
    target: bool (H, W) M^v, or its :class:`~r360gpu.kernels.mask_iou.PackedMasks`.
    n_instances: (K_pre, K_post) for the record.
    """
    r = K.mask_iou(preds, target, ctx=ctx)
    if r.iou.shape != (2, 1):
        raise InputError(f"expected the 2 predicted masks [pre, post] and one target, got IoU shape {r.iou.shape}")
    area_t = int(r.area_b[0])
    return SemanticView(
        iou_pre=float(r.iou[0, 0]),
        iou_post=float(r.iou[1, 0]),
        empty_target=area_t == 0,
        area_target=area_t,
        area_pred_pre=int(r.area_a[0]),
        area_pred_post=int(r.area_a[1]),
        inter_pre=int(r.intersection[0, 0]),
        inter_post=int(r.intersection[1, 0]),
        n_instances_pre=int(n_instances[0]),
        n_instances_post=int(n_instances[1]),
        probe=probe,
    )


def predicted_unions(pred_pre, pred_post, size: tuple[int, int], *, view: str = "", ctx=None):
    """(M̂_pre, M̂_post, (K_pre, K_post)): the predicted masks as bool (H, W).

    pred_pre, pred_post: :class:`~r360gpu.probes.base.SemanticPrediction`,
        bool/integer (K, H, W) instance stacks, (H, W) masks, or None (no
        detection -> empty mask).
    """
    a = mask_stack(pred_pre, size, "predicted masks on I_pre", view)
    b = mask_stack(pred_post, size, "predicted masks on I_post", view)
    return _predicted_union(a, ctx), _predicted_union(b, ctx), (a.shape[0], b.shape[0])


def semantic_view(pred_pre, pred_post, target, *, view: str = "", ctx=None) -> SemanticView:
    """Semantic measurement of one view.

    pred_pre, pred_post: the semantic probe's output on I_pre and I_post:
        :class:`~r360gpu.probes.base.SemanticPrediction`, bool/integer
        (K, H, W) instance stacks, (H, W) masks, or None (no detection).
    target: (H, W) target mask M^v, non-zero = target.
    view: view name, used in error messages.
    """
    m = target_mask(target, view)
    u_pre, u_post, counts = predicted_unions(pred_pre, pred_post, m.shape, view=view, ctx=ctx)
    return semantic_view_from_unions(
        np.stack([u_pre, u_post]), m, n_instances=counts, probe=probe_name(pred_pre, pred_post), ctx=ctx
    )


def acc_seg(iou_post: Sequence[float], xi: float = XI_DEFAULT) -> float | None:
    """acc_seg,ξ: fraction of the values with IoU_post < ξ (None for no values)."""
    x = check_xi(xi)
    vals = np.asarray(iou_post, np.float64)
    if vals.size == 0:
        return None
    return float(np.count_nonzero(vals < x) / vals.size)


@dataclass(frozen=True)
class SemanticSummary:
    """Semantic axis over a set of views (one scene, one method, one probe).

    n_views: views given; n_scored: views in the means; n_empty_target: views
    with an empty M^v (excluded unless ``include_empty_targets``).
    iou_pre, iou_post, iou_drop: means over the scored views (None if none).
    acc_seg: {ξ: acc_seg,ξ} (None if no view is scored); always holds ξ = 0.3.
    """

    n_views: int
    n_scored: int
    n_empty_target: int
    include_empty_targets: bool
    iou_pre: float | None
    iou_post: float | None
    iou_drop: float | None
    acc_seg: dict[float, float | None] = field(default_factory=dict)

    @property
    def s_sem(self) -> float | None:
        """The semantic axis, acc_seg at ξ = 0.3."""
        return self.acc_seg[XI_DEFAULT]

    def to_dict(self) -> dict:
        return {
            "n_views": self.n_views,
            "n_scored": self.n_scored,
            "n_empty_target": self.n_empty_target,
            "include_empty_targets": self.include_empty_targets,
            "iou_pre": self.iou_pre,
            "iou_post": self.iou_post,
            "iou_drop": self.iou_drop,
            "acc_seg": {json_values.xi_key(x): v for x, v in self.acc_seg.items()},
            "s_sem": self.s_sem,
        }


def scored_views(views: Sequence[SemanticView], include_empty_targets: bool = False) -> list[SemanticView]:
    """The views that enter the means (all, or those with a non-empty target)."""
    return [v for v in views if include_empty_targets or not v.empty_target]


def semantic_summary(
    views: Sequence[SemanticView],
    xis: Iterable[float] = (XI_DEFAULT,),
    *,
    include_empty_targets: bool = False,
) -> SemanticSummary:
    """Means and acc_seg over views.  ``xis``: thresholds to report (0.3 is always added)."""
    thresholds = sorted({check_xi(x) for x in xis} | {XI_DEFAULT})
    scored = scored_views(views, include_empty_targets)
    n_empty = sum(1 for v in views if v.empty_target)

    def mean(vals):
        return float(np.mean(vals)) if vals else None

    post = [v.iou_post for v in scored]
    return SemanticSummary(
        n_views=len(views),
        n_scored=len(scored),
        n_empty_target=n_empty,
        include_empty_targets=include_empty_targets,
        iou_pre=mean([v.iou_pre for v in scored]),
        iou_post=mean(post),
        iou_drop=mean([v.iou_drop for v in scored]),
        acc_seg={x: acc_seg(post, x) for x in thresholds},
    )
