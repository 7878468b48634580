"""The scene in 3D: the target over pre's Gaussians, its masks at any pose, orbits, residuals.

This package consumes render outputs (the renderer's projection, sort and
tile lists) and target masks; nothing upstream imports it.

Library (numpy arrays in, numpy out; masks may also be float32 wgpu buffers
on the context's device, and `target_masks` can leave its output there)::

    lift_target(scene, cameras, masks, *, ctx=None, options=None) -> LiftedTarget
        scene: Gaussians (N); cameras: [Camera]; masks: [(H, W) bool/float32 or wgpu buffer]
        LiftedTarget.target (N,) bool, .w_in / .w_out (N,) float64, .indices (K,) int64
    target_from_indices(n, indices) / load_indices(path, n) / target_from_box(means, Box)
    target_masks(scene, target, cameras, *, ctx=None, output="numpy"|"device")
        target: (N,) bool -> yields (H, W) bool per camera (or a DeviceRender, plane "r" = share)
    orbit_cameras(centre, cameras, n) -> [Camera] (n poses around centre (3,))
    residuals(gaussians, cameras, masks, flagged, *, behind=None, ctx=None) -> (N,) float64 in [0, 1]
        behind: None or per camera the (H, W) float32 depth of the surface behind the object
        (surface_depth(reference, cameras) or depth_behind(pre, target, cameras))
    MaskLifter, TargetMaskRenderer    the device passes (weights / masks stay on the GPU)
"""
from __future__ import annotations

from .device import MaskLifter
from .masks import MASK_SHARE, TargetMaskRenderer, label_scene, target_masks
from .orbit import keep_pose, orbit_cameras
from .residuals import (depth_behind, flagged_views, in_front, residuals, surface_depth, top_residuals,
                        write_residual_ply)
from .target import (MIN_SHARE, MIN_WEIGHT, Box, LiftedTarget, decide, lift_target, load_indices,
                     target_from_box, target_from_indices)

__all__ = [
    "MASK_SHARE", "MIN_SHARE", "MIN_WEIGHT", "Box", "LiftedTarget", "MaskLifter", "TargetMaskRenderer",
    "decide", "depth_behind", "flagged_views", "in_front", "keep_pose", "label_scene", "lift_target",
    "load_indices", "orbit_cameras", "residuals", "surface_depth", "target_from_box", "target_from_indices",
    "target_masks", "top_residuals", "write_residual_ply",
]
