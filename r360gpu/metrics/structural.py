"""Structural axis: sim_SAM and s_str (paper eq. sim_sam_matching, eq. sim_sam,
eq. sim_sam_overall, eq. structural_axis; docs/protocol.md).

Per view ``v`` a prompt-free probe (SAM-style automatic masks) gives a mask
set on each of the two renderings compared:

* ``mode="reference"``: A = masks on I_post, B = masks on I_ref, and
  ``s_str = sim_SAM`` (agreement with the physical post-removal scene);
* ``mode="reference_free"``: A = masks on I_pre, B = masks on I_post, and
  ``s_str = 1 - sim_SAM`` (structural change in the removed region).

A probe mask is *retained* when ``IoU(mask, M^v) >= 0.1``.  With N_v, M_v the
sizes of the retained sets, the IoU matrix between them is solved for the
one-to-one assignment that maximises the summed IoU (Hungarian,
``scipy.optimize.linear_sum_assignment(maximize=True)``) and

    sim^v = 1                                  if N_v = M_v = 0,
    sim^v = 0                                  if exactly one set is empty,
    sim^v = sum of matched IoUs / max(N_v, M_v) otherwise;

``sim_SAM`` is the mean of sim^v over views.  All IoUs come from the GPU mask
kernels (:mod:`r360gpu.kernels.mask_iou`).

Empty target mask: no mask can reach IoU 0.1 with an empty M^v, so both
retained sets are empty and the formula gives sim^v = 1, a value that says
nothing about the removal.  Such a view is flagged ``empty_target`` and, as on
the other axes, excluded from the means unless ``include_empty_targets``.

We follow the paper.  Where the public reference code
(github.com/simonakocour/anything_left, ``remove360/evaluation/sam.py``
``evaluate_sam_scene`` and ``scripts/run_pipeline.py``) differs:

* its "ground truth" side is SAM run on ``images/before`` (the captured
  pre-removal photographs), compared with SAM on the method's post-removal
  renders; the paper compares I_post with I_ref (or I_pre with I_post);
* it skips a view (no value at all, not in the mean) when *either* retained
  set is empty, so the paper's 1 (both empty) and 0 (one empty) cases never
  reach its mean; its ``... else 0.0`` branch for both-empty sets is dead code
  after that skip;
* it retains with ``IoU >= 0.1`` (as here and in the protocol's ``RETAIN_IOU``), while the
  paper's text says the overlap "exceeds 0.1";
* it resizes SAM masks to the target mask's size with nearest-neighbour
  interpolation and binarises the target PNG at > 128; here mask stacks
  of another size are an input error (resizing is the loaders' job) and the
  target is "non-zero = target";
* its match list keeps only assigned pairs with IoU > 0; the sum is the
  same, and :class:`StructuralView` records the same pairs.
"""
from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..kernels import mask_iou as K
from ..protocol import RETAIN_IOU, STRUCTURAL_MODES
from . import json_values
from ._masks import mask_stack, probe_name, target_mask

MODES = STRUCTURAL_MODES  # short local name


def check_mode(mode: str) -> str:
    if mode not in MODES:
        raise InputError(f"structural mode must be one of {MODES}, got {mode!r}")
    return mode


@dataclass(frozen=True)
class StructuralView:
    """Structural measurement of one view by one probe.

    sim_sam: sim^v in [0, 1].
    n_a, n_b: N_v and M_v, the sizes of the retained sets A and B.
    retained_a, retained_b: indices of the retained masks in the probe's
        mask sets on the two renderings (ascending).
    pairs: the assigned pairs with IoU > 0, as (index in the set on the first
        rendering, index in the set on the second), original probe indices;
        pairs of IoU 0 add nothing to the sum and are left out.
    pair_iou: IoU of each pair, same order.
    empty_target: M^v has no pixel.
    area_target: pixel count of M^v.
    mode: "reference" (A on I_post, B on I_ref) or "reference_free"
        (A on I_pre, B on I_post).
    probe: name of the structural probe.
    """

    sim_sam: float
    n_a: int
    n_b: int
    retained_a: tuple[int, ...]
    retained_b: tuple[int, ...]
    pairs: tuple[tuple[int, int], ...]
    pair_iou: tuple[float, ...]
    empty_target: bool
    area_target: int
    mode: str
    probe: str = ""

    @property
    def s_str(self) -> float:
        """This view's oriented structural score: sim^v with a reference,
        1 - sim^v without (higher is better in both modes)."""
        return self.sim_sam if self.mode == "reference" else 1.0 - self.sim_sam

    def to_dict(self) -> dict:
        return {
            "probe": self.probe,
            "mode": self.mode,
            "sim_sam": self.sim_sam,
            "s_str": self.s_str,
            "n_a": self.n_a,
            "n_b": self.n_b,
            "retained_a": list(self.retained_a),
            "retained_b": list(self.retained_b),
            "pairs": [list(p) for p in self.pairs],
            "pair_iou": list(self.pair_iou),
            "empty_target": self.empty_target,
            "area_target": self.area_target,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "StructuralView":
        what = "structural view record"
        f = lambda k: json_values.field(d, k, what)  # noqa: E731
        pairs = tuple((int(p[0]), int(p[1])) for p in f("pairs"))
        ious = tuple(float(x) for x in f("pair_iou"))
        if len(pairs) != len(ious):
            raise InputError(f"{what}: {len(pairs)} pairs but {len(ious)} pair IoUs")
        return cls(
            sim_sam=float(f("sim_sam")),
            n_a=int(f("n_a")),
            n_b=int(f("n_b")),
            retained_a=tuple(int(i) for i in f("retained_a")),
            retained_b=tuple(int(i) for i in f("retained_b")),
            pairs=pairs,
            pair_iou=ious,
            empty_target=bool(f("empty_target")),
            area_target=int(f("area_target")),
            mode=check_mode(f("mode")),
            probe=str(d.get("probe", "")),
        )


def match(iou: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Optimal one-to-one assignment maximising the summed IoU.

    iou: (N, M) float64 IoU matrix.  Returns (rows, cols, total): the assigned
    index pairs (min(N, M) of them) and their summed IoU.
    """
    iou = np.asarray(iou, np.float64)
    if iou.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), 0.0
    rows, cols = linear_sum_assignment()(iou, maximize=True)
    return rows, cols, float(iou[rows, cols].sum())


@functools.cache
def linear_sum_assignment():
    """``scipy.optimize.linear_sum_assignment``, loaded without the ``scipy.optimize`` package where
    scipy keeps it as its own compiled module (``scipy/optimize/_lsap``, scipy >= 1.6): the package
    imports scipy.linalg, scipy.special and the rest, which a run that needs this one function
    does not use (docs/benchmarks.md: where the time goes against the input floor).
    The same function (tests/test_metrics_structural.py); anything else gets the package's."""
    import importlib.machinery
    import importlib.util

    try:
        spec = importlib.util.find_spec("scipy")
        folder = Path(spec.origin).parent / "optimize"
        found = [folder / f"_lsap{suffix}" for suffix in importlib.machinery.EXTENSION_SUFFIXES
                 if (folder / f"_lsap{suffix}").is_file()]
        if found:
            loader = importlib.machinery.ExtensionFileLoader("scipy.optimize._lsap", str(found[0]))
            module = importlib.util.module_from_spec(
                importlib.util.spec_from_file_location("scipy.optimize._lsap", found[0], loader=loader))
            loader.exec_module(module)
            return module.linear_sum_assignment
    except (ImportError, AttributeError, OSError, TypeError):
        pass
    from scipy.optimize import linear_sum_assignment as lsa

    return lsa


def sim_from_matching(n_a: int, n_b: int, total: float) -> float:
    """sim^v from the set sizes and the summed matched IoU (eq. sim_sam)."""
    if n_a == 0 and n_b == 0:
        return 1.0
    if n_a == 0 or n_b == 0:
        return 0.0
    return total / max(n_a, n_b)


def retained(iou_with_target: np.ndarray, retain_iou: float = RETAIN_IOU) -> np.ndarray:
    """Indices (ascending, int64) of the masks whose IoU with M^v is >= retain_iou."""
    return np.flatnonzero(np.asarray(iou_with_target) >= retain_iou).astype(np.int64)


def structural_from_ious(
    keep_a: np.ndarray,
    keep_b: np.ndarray,
    iou_ab: np.ndarray,
    *,
    area_target: int,
    mode: str,
    probe: str = "",
) -> StructuralView:
    """StructuralView from the retained indices and their IoU matrix.

    keep_a, keep_b: retained indices (:func:`retained`) into the two sets.
    iou_ab: (len(keep_a), len(keep_b)) IoU matrix of the retained masks.
    """
    iou_ab = np.asarray(iou_ab, np.float64).reshape(len(keep_a), len(keep_b))
    rows, cols, total = match(iou_ab)
    vals = iou_ab[rows, cols]
    pos = vals > 0
    return StructuralView(
        sim_sam=sim_from_matching(len(keep_a), len(keep_b), total),
        n_a=len(keep_a),
        n_b=len(keep_b),
        retained_a=tuple(int(i) for i in keep_a),
        retained_b=tuple(int(i) for i in keep_b),
        pairs=tuple((int(keep_a[r]), int(keep_b[c])) for r, c in zip(rows[pos], cols[pos])),
        pair_iou=tuple(float(v) for v in vals[pos]),
        empty_target=area_target == 0,
        area_target=int(area_target),
        mode=check_mode(mode),
        probe=probe,
    )


def structural_view(
    masks_a,
    masks_b,
    target,
    *,
    mode: str,
    retain_iou: float = RETAIN_IOU,
    view: str = "",
    ctx=None,
    packs: K.PackMemo | None = None,
) -> StructuralView:
    """sim^v of one view.

    masks_a, masks_b: the probe's masks on the first and second rendering of
        ``mode`` (reference: I_post, I_ref; reference_free: I_pre, I_post):
        :class:`~r360gpu.probes.base.MaskSet`, bool/integer (K, H, W) stacks,
        or None (no masks).
    target: (H, W) target mask M^v, non-zero = target.
    retain_iou: retention threshold on IoU(mask, M^v) (paper: 0.1).
    view: view name, used in error messages.
    packs: packs kept across the calls of one view (the same masks are then packed once).
    """
    check_mode(mode)
    m = target_mask(target, view)
    a = mask_stack(masks_a, m.shape, "structural probe masks (first rendering)", view)
    b = mask_stack(masks_b, m.shape, "structural probe masks (second rendering)", view)
    packs = packs if packs is not None else K.PackMemo(ctx)
    pa, pb = packs.pack(a), packs.pack(b)
    t = K.pack(m, ctx=ctx)
    ra = K.mask_iou(pa, t, ctx=ctx)
    rb = K.mask_iou(pb, t, ctx=ctx)
    area_t = int(rb.area_b[0])
    keep_a = retained(ra.iou[:, 0], retain_iou)
    keep_b = retained(rb.iou[:, 0], retain_iou)
    if len(keep_a) and len(keep_b):
        iou_ab = K.mask_iou(K.take(pa, keep_a, a, ctx=ctx), K.take(pb, keep_b, b, ctx=ctx), ctx=ctx).iou
    else:
        iou_ab = np.zeros((len(keep_a), len(keep_b)))
    return structural_from_ious(
        keep_a, keep_b, iou_ab, area_target=area_t, mode=mode, probe=probe_name(masks_a, masks_b)
    )


@dataclass(frozen=True)
class StructuralSummary:
    """Structural axis over a set of views (one scene, one method, one probe).

    mode: "reference" or "reference_free".
    n_views, n_scored, n_empty_target: as in the semantic summary.
    sim_sam: mean sim^v over the scored views (None if none).
    s_str: sim_sam (reference) or 1 - sim_sam (reference-free); None if none.
    """

    mode: str
    n_views: int
    n_scored: int
    n_empty_target: int
    include_empty_targets: bool
    sim_sam: float | None
    s_str: float | None

    def to_dict(self) -> dict:
        return {
            "mode": self.mode,
            "n_views": self.n_views,
            "n_scored": self.n_scored,
            "n_empty_target": self.n_empty_target,
            "include_empty_targets": self.include_empty_targets,
            "sim_sam": self.sim_sam,
            "s_str": self.s_str,
        }


def common_mode(views: Sequence[StructuralView], mode: str | None = None) -> str:
    """The one mode shared by all views (or ``mode`` when there are none)."""
    modes = {v.mode for v in views}
    if mode is not None:
        modes.add(check_mode(mode))
    if len(modes) > 1:
        raise InputError(f"structural views mix modes {sorted(modes)}; s_str needs one mode")
    if not modes:
        raise InputError("no structural views and no mode given")
    return modes.pop()


def structural_summary(
    views: Sequence[StructuralView],
    *,
    mode: str | None = None,
    include_empty_targets: bool = False,
) -> StructuralSummary:
    """sim_SAM and s_str over views.  ``mode`` is needed only for an empty list."""
    md = common_mode(views, mode)
    scored = [v for v in views if include_empty_targets or not v.empty_target]
    sim = float(np.mean([v.sim_sam for v in scored])) if scored else None
    s = None if sim is None else (sim if md == "reference" else 1.0 - sim)
    return StructuralSummary(
        mode=md,
        n_views=len(views),
        n_scored=len(scored),
        n_empty_target=sum(1 for v in views if v.empty_target),
        include_empty_targets=include_empty_targets,
        sim_sam=sim,
        s_str=s,
    )
