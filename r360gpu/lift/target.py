"""The target in 3D: which of pre's Gaussians are the object to remove.

Three ways in, one result (:class:`LiftedTarget`, an (N,) bool over pre's
Gaussians):

* masks of a few views, lifted by alpha compositing (:func:`lift_target`):
  per Gaussian g, ``w_in[g]`` and ``w_out[g]`` sum its compositing weight
  ``alpha T`` over every pixel of every given view, weighted by the mask
  value there and by one minus it.  g is target when
  ``w_in / (w_in + w_out) >= MIN_SHARE`` and ``w_in + w_out >= MIN_WEIGHT``.
  This is FlashSplat's closed form for two labels (Shen et al., "FlashSplat:
  2D to 3D Gaussian Splatting Segmentation Solved Optimally", ECCV 2024): the
  assignment that minimises the rendered-mask error is, per Gaussian, the
  label holding the larger share of its accumulated weight.  The floor leaves
  out Gaussians the views barely see (their label is a coin toss).
* Gaussian indices (:func:`target_from_indices`, :func:`load_indices`: a
  ``.npy`` of indices or booleans, or a PLY whose vertex property is non-zero
  on the target);
* a box (:class:`Box`, axis-aligned or oriented): Gaussians whose centre is
  inside.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.box import Box

#: A Gaussian is target when at least this share of its compositing weight falls inside the masks.
MIN_SHARE = 0.5
#: ...and its summed weight over all given pixels is at least this (units: one fully opaque pixel).
MIN_WEIGHT = 0.05
#: A target of more than this share of pre's Gaussians is warned about (a box in other units, say).
MAX_TARGET_SHARE = 0.5


@dataclass(frozen=True)
class LiftedTarget:
    """The target over pre's N Gaussians.

    target: (N,) bool.  source: "masks", "indices" or "box".  w_in / w_out:
    (N,) float64 compositing weight inside / outside the masks (source
    "masks" only, else None).  views: names of the views whose masks were
    lifted (source "masks").  w_capture: (N,) float64 each Gaussian's whole compositing weight
    over the cameras given to ``lift_target(capture=...)``, else None.
    """

    target: np.ndarray
    source: str
    w_in: np.ndarray | None = None
    w_out: np.ndarray | None = None
    views: tuple = field(default_factory=tuple)
    #: (V, 2, N) float64: each given view's own (w_in, w_out), in ``views``' order (lift_target(per_view=True)).
    w_views: np.ndarray | None = None
    w_capture: np.ndarray | None = None

    @property
    def indices(self) -> np.ndarray:
        """(K,) int64 indices of the target Gaussians."""
        return np.flatnonzero(self.target).astype(np.int64)

    @property
    def n(self) -> int:
        return int(self.target.shape[0])

    def extent(self, means: np.ndarray) -> tuple[np.ndarray, float]:
        """(centre (3,), radius) of the target's centres ``means`` (N, 3): their per-axis median and
        90th-percentile distance from it, each weighted by ``w_in`` when lifted from masks (the
        Gaussians that show the target most say where it is; background seen only through the
        object's gaps, which the masks cannot tell from it, counts for little)."""
        pts = np.asarray(means, np.float64)[self.target]
        if len(pts) == 0:
            raise InputError("the target has no Gaussians")
        w = np.ones(len(pts)) if self.w_in is None else np.asarray(self.w_in, np.float64)[self.target]
        if not w.sum() > 0:
            w = np.ones(len(pts))
        centre = np.array([_weighted_quantile(pts[:, k], w, 0.5) for k in range(3)])
        radius = _weighted_quantile(np.linalg.norm(pts - centre, axis=1), w, 0.9)
        return centre, max(float(radius), 1e-6)


def _weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """The smallest value whose cumulative weight share reaches ``q``."""
    order = np.argsort(values, kind="stable")
    cum = np.cumsum(weights[order])
    return float(values[order][min(np.searchsorted(cum, q * cum[-1]), len(cum) - 1)])


def decide(w_in: np.ndarray, w_out: np.ndarray, *, min_share: float = MIN_SHARE,
           min_weight: float = MIN_WEIGHT) -> np.ndarray:
    """(N,) bool: share ``w_in / (w_in + w_out) >= min_share`` and total ``>= min_weight``."""
    w_in = np.asarray(w_in, np.float64)
    total = w_in + np.asarray(w_out, np.float64)
    return (total >= min_weight) & (w_in >= min_share * total) & (total > 0)


def lift_target(scene, cameras, masks, *, ctx=None, options=None, frame=None, min_share: float = MIN_SHARE,
                min_weight: float = MIN_WEIGHT, per_view: bool = False, capture=None) -> LiftedTarget:
    """Lift target masks of some views to pre's Gaussians (see the module docstring).

    scene: `Gaussians` (N Gaussians).
    cameras: sequence of `Camera`.
    masks: one per camera: (H, W) bool or float32 in [0, 1] at the camera's
        size, or a wgpu buffer of H x W float32 (row-major) on ``ctx``'s device.
    options: `RenderOptions` the scene is
        rendered with (the weights are the renderer's own).
    frame: the scene's world frame (a `Frame`; None: the cameras'), each camera
        moved into it (`r360gpu.io.frames.in_frame`).
    per_view: also keep each view's own weights (``w_views``; the accumulators are read after each
        view: the sums are exact fixed point, so the differences are each view's exactly).
    capture: None, or cameras (the evaluation cameras) over which each Gaussian's whole weight is
        also summed (``w_capture``): in the mask's pass where a camera is one of ``cameras`` (the
        same object), so its projection and sort serve both.
    Returns a `LiftedTarget` with w_in, w_out (N,) float64.
    """
    from ..io.frames import in_frame
    from .device import MaskLifter

    cameras, masks = list(cameras), list(masks)
    if len(cameras) != len(masks):
        raise InputError(f"lift_target: {len(cameras)} cameras but {len(masks)} masks")
    if not cameras:
        raise InputError("lift_target: no views to lift the target from")
    also = {id(c): c for c in capture or ()}
    lifter = MaskLifter(scene, ctx=ctx, options=options, capture=capture is not None)
    try:
        lifter.reset()
        sums = []
        for cam, m in zip(cameras, masks):
            lifter.add_view(in_frame(frame, cam), m, capture=also.pop(id(cam), None) is not None)
            if per_view:
                sums.append(np.stack(lifter.weights()))
        for cam in also.values():  # evaluation cameras with no mask to lift
            lifter.add_view(in_frame(frame, cam), None, capture=True)
        w_in, w_out = sums[-1] if per_view else lifter.weights()
        w_capture = None if capture is None else lifter.capture_weights()
    finally:
        lifter.release()
    w_views = np.diff(np.stack(sums), axis=0, prepend=0.0) if per_view else None
    return LiftedTarget(decide(w_in, w_out, min_share=min_share, min_weight=min_weight), "masks", w_in, w_out,
                        tuple(getattr(c, "name", "") for c in cameras), w_views, w_capture)


def target_from_indices(n: int, indices, *, where: str = "indices", rows=None, warn=None) -> LiftedTarget:
    """The target given as Gaussian indices (int array, any order, duplicates allowed) or an (n,) bool mask.

    n: the rows of pre's file the indices refer to; rows: None, or the (M,) file row of each loaded
    Gaussian when the loader dropped invalid rows (`r360gpu.io.Gaussians.rows`): the result is
    over the M loaded Gaussians, and target rows that were dropped are warned about (``warn``).

    Refused (InputError naming ``where``): anything but a flat array of whole numbers or booleans
    (`r360gpu.io.indices.index_array`), indices outside 0..n-1, an n-long array of 0s and 1s
    (a boolean mask saved as integers: read as indices it would select Gaussians 0 and 1), and a
    target of no Gaussian.
    """
    from ..io.indices import index_array

    idx = index_array(indices, where)
    sel = np.zeros(int(n), bool)
    if idx.dtype == bool:
        if idx.shape != (n,):
            raise InputError(f"{where}: a boolean target needs one entry per Gaussian ({n}), got shape {idx.shape}")
        sel[:] = idx
    else:
        if n > 2 and idx.shape == (n,) and np.isin(idx, (0, 1)).all():
            raise InputError(f"{where}: {n} entries, each 0 or 1: a mask over pre's {n} Gaussians saved as "
                             f"integers (as indices it selects Gaussians 0 and 1 only); save it as booleans "
                             f"(mask.astype(bool))")
        bad = idx[(idx < 0) | (idx >= n)]
        if bad.size:
            raise InputError(f"{where}: {bad.size} target indices outside 0..{n - 1} (e.g. {int(bad[0])}); "
                             "are they indices into pre's Gaussians?")
        sel[idx] = True
    if not sel.any():
        raise InputError(f"{where}: the target has no Gaussians")
    if rows is not None:
        file_sel, sel = sel, sel[np.asarray(rows)]
        lost = int(file_sel.sum() - sel.sum())
        if lost and warn is not None:
            warn(f"{where}: {lost} of the {int(file_sel.sum())} target rows are Gaussians pre's loader dropped "
                 f"(invalid values); the target is the other {int(sel.sum())}")
    return LiftedTarget(sel, "indices")


def check_extent(lifted: LiftedTarget, where: str, warn=None) -> LiftedTarget:
    """``lifted`` unless it holds no Gaussian or every one of pre's (a box in other units, masks
    that cover every view): InputError naming ``where``.  More than :data:`MAX_TARGET_SHARE` of
    pre's Gaussians is doubtful (an object to remove is rarely most of a scene) and is warned
    about (``warn``)."""
    k, n = int(lifted.target.sum()), lifted.n
    if k == 0:
        raise InputError(f"{where}: the target ({lifted.source}) holds no Gaussian of pre")
    if k == n:
        hint = {"box": "is the box in the scene's units?", "masks": "do the masks cover every pixel?",
                "indices": "are these the object's indices?"}[lifted.source]
        raise InputError(f"{where}: the target ({lifted.source}) is every one of pre's {n} Gaussians, so "
                         f"nothing would be left; {hint}")
    if k > MAX_TARGET_SHARE * n and warn is not None:
        warn(f"{where}: the target ({lifted.source}) is {k} of pre's {n} Gaussians ({100 * k / n:.0f}%), most of "
             f"the scene; is that the object to remove?")
    return lifted


def load_indices(path: str | os.PathLike, n: int, *, prop: str | None = None, rows=None,
                 warn=None) -> LiftedTarget:
    """Target indices from a file: ``.npy`` (indices, or (n,) bool) or ``.ply`` (vertex
    property ``prop``, default the first of "target", "label", "is_target", non-zero = target;
    the PLY must have one vertex per row of pre's file).  n, rows, warn: as `target_from_indices`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: target indices file does not exist")
    if path.suffix.lower() == ".npy":
        from ..io.npy import read_npy

        return target_from_indices(n, read_npy(path), where=str(path), rows=rows, warn=warn)
    if path.suffix.lower() == ".ply":
        from ..io.ply import read_ply

        ply = read_ply(path)
        vert = ply.arrays.get("vertex")
        if vert is None:
            element = ply.element("vertex")
            if element is not None and element.has_lists:  # read_ply keeps no array for such an element
                lists = [q.name for q in element.properties if q.is_list]
                raise InputError(f"{path}: the vertex element has list properties ({', '.join(lists)}), which "
                                 f"r360gpu does not read; write the target label as one number per vertex")
            raise InputError(f"{path}: PLY has no vertex element")
        names = vert.dtype.names or ()
        choice = [prop] if prop else [p for p in ("target", "label", "is_target") if p in names]
        if not choice or choice[0] not in names:
            raise InputError(f"{path}: no target property ({prop or 'target, label or is_target'}) among "
                             f"{', '.join(names)}")
        if len(vert) != n:
            raise InputError(f"{path}: {len(vert)} vertices, pre's file has {n} Gaussians")
        label = np.asarray(vert[choice[0]])
        if label.dtype.kind == "f" and np.isnan(label).any():  # neither zero nor non-zero: not a label
            raise InputError(f"{path}: vertex property {choice[0]!r} is NaN at {int(np.isnan(label).sum())} of "
                             f"{len(label)} vertices (e.g. vertex {int(np.flatnonzero(np.isnan(label))[0])}); a "
                             f"target label is non-zero on the target and 0 elsewhere")
        values = np.unique(label[label != 0])
        if warn is not None and (values.size > 1 or (values.size and values[0] < 0)):
            # -1 is a common "unlabelled", and several values a map of object ids: both read as target
            warn(f"{path}: vertex property {choice[0]!r} takes {values.size} non-zero value(s) "
                 f"({', '.join(f'{v:g}' for v in values[:4].tolist())}{', ...' if values.size > 4 else ''}); every "
                 f"vertex where it is non-zero is target: is it a map of object ids, or -1 for unlabelled? "
                 f"(a target label is 1 on the target and 0 elsewhere)")
        return target_from_indices(n, label != 0, where=str(path), rows=rows, warn=warn)
    raise InputError(f"{path}: target indices must be a .npy or .ply file")


def target_from_box(means: np.ndarray, box: Box, *, where: str | None = None) -> LiftedTarget:
    """The Gaussians whose centre (means (N, 3)) is inside ``box`` (``where``: the file that gave it)."""
    sel = box.contains(means)
    if not sel.any():
        raise InputError(f"no Gaussian centre lies in the target box (centre {box.centre.tolist()}, "
                         f"half-size {box.half.tolist()}); is the box in the scene's units?", where)
    return LiftedTarget(sel, "box")
