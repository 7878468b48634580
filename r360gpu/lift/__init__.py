"""The target in 3D and its masks at any pose (consumes render outputs and target masks).

Public API::

    lift_target(scene, cameras, masks, *, ctx=None, options=None) -> LiftedTarget
    target_from_indices(n, indices) / load_indices(path, n) / target_from_box(means, Box)
    target_masks(scene, target, cameras, *, ctx=None, output="numpy") -> iterator of (H, W) bool
    MaskLifter, TargetMaskRenderer    the device passes (weights / masks stay on the GPU)
"""
from __future__ import annotations

from .device import MaskLifter
from .masks import MASK_SHARE, TargetMaskRenderer, label_scene, target_masks
from .target import (MIN_SHARE, MIN_WEIGHT, Box, LiftedTarget, decide, lift_target, load_indices,
                     target_from_box, target_from_indices)

__all__ = [
    "MASK_SHARE", "MIN_SHARE", "MIN_WEIGHT", "Box", "LiftedTarget", "MaskLifter", "TargetMaskRenderer",
    "decide", "label_scene", "lift_target", "load_indices", "target_from_box", "target_from_indices",
    "target_masks",
]
