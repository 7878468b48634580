"""The input of the aggregation layer: one value per (scene, method) and axis.

An :class:`AxisCells` holds the three scene-level removal-quality axes
(``s_sem``, ``s_geo``, ``s_str``; paper eq. ``eq:rqs``) for every method on
every scene, optionally the number of evaluation views behind each cell (for
view-weighted pooling) and the diagnostic ``iou_drop``.  It is a complete
scenes x methods grid: every method covers the same scenes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..protocol import AXES  # the three RQS axes, in the paper's order (re-exported: aggregate.AXES)


def _as_grid(name: str, values, shape: tuple[int, int]) -> np.ndarray:
    arr = np.array(values, dtype=np.float64)
    if arr.shape != shape:
        raise InputError(f"{name} has shape {arr.shape}, expected (scenes, methods) = {shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains a non-finite value")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class AxisCells:
    """Scene-level axis values for a scenes x methods grid.

    Attributes:
        scenes: the S scene names, in display order (unique).
        methods: the M method names, in display order (unique).
        s_sem, s_geo, s_str: float64 arrays of shape (S, M), values in [0, 1],
            higher is better (``s_sem = acc_seg,0.3``, ``s_geo = acc_depth``,
            ``s_str = sim_SAM`` with a reference or ``1 - sim_SAM`` without).
        n_views: optional float64 array (S, M) of positive view counts behind
            each cell; when given, pooling over scenes is view-weighted.
        iou_drop: optional float64 array (S, M) in [-1, 1]; a diagnostic that
            never enters RQS or ranks.

    Arrays are copied and made read-only.  Invalid shapes or values raise
    :class:`~r360gpu.errors.InputError`.
    """

    scenes: tuple[str, ...]
    methods: tuple[str, ...]
    s_sem: np.ndarray
    s_geo: np.ndarray
    s_str: np.ndarray
    n_views: np.ndarray | None = None
    iou_drop: np.ndarray | None = None

    def __post_init__(self) -> None:
        scenes = tuple(str(s) for s in self.scenes)
        methods = tuple(str(m) for m in self.methods)
        if not scenes or not methods:
            raise InputError("need at least one scene and one method")
        for kind, names in (("scene", scenes), ("method", methods)):
            if len(set(names)) != len(names):
                raise InputError(f"{kind} names are not unique: {list(names)}")
        shape = (len(scenes), len(methods))
        object.__setattr__(self, "scenes", scenes)
        object.__setattr__(self, "methods", methods)
        for name in AXES:
            arr = _as_grid(name, getattr(self, name), shape)
            if arr.min() < 0.0 or arr.max() > 1.0:
                raise InputError(f"{name} has values outside [0, 1]")
            object.__setattr__(self, name, arr)
        if self.n_views is not None:
            arr = _as_grid("n_views", self.n_views, shape)
            if arr.min() <= 0.0:
                raise InputError("n_views must be positive")
            object.__setattr__(self, "n_views", arr)
        if self.iou_drop is not None:
            arr = _as_grid("iou_drop", self.iou_drop, shape)
            if arr.min() < -1.0 or arr.max() > 1.0:
                raise InputError("iou_drop has values outside [-1, 1]")
            object.__setattr__(self, "iou_drop", arr)

    @property
    def axes(self) -> np.ndarray:
        """The three axes stacked: float64 array (S, M, 3) in :data:`AXES` order."""
        return np.stack([self.s_sem, self.s_geo, self.s_str], axis=-1)
