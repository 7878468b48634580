"""The scene in 3D: the target over pre's Gaussians, its masks at any pose, orbits, residuals.

This package consumes render outputs (the renderer's projection, sort and
tile lists) and target masks; nothing upstream imports it.

Library (numpy arrays in, numpy out; masks may also be float32 wgpu buffers
on the context's device, and `target_masks` can leave its output there)::

    lift_target(scene, cameras, masks, *, ctx=None, options=None, frame=None, per_view=False) -> LiftedTarget
        scene: Gaussians (N); cameras: [Camera]; masks: [(H, W) bool/float32 or wgpu buffer]
        LiftedTarget.target (N,) bool, .w_in / .w_out (N,) float64, .indices (K,) int64,
        .w_views (V, 2, N) float64 per view (per_view=True)
    target_from_indices(n, indices) / load_indices(path, n) / target_from_box(means, Box)
    target_masks(scene, target, cameras, *, ctx=None, frame=None, output="numpy"|"device")
        target: (N,) bool -> yields (H, W) bool per camera (or a DeviceRender, plane "r" = share)
    orbit_cameras(centre, cameras, n) -> [Camera] (n poses around centre (3,))
    residuals(gaussians, cameras, masks, flagged, *, behind=None, ctx=None, frame=None) -> (N,) float64 in [0, 1]
        behind: None or per camera the (H, W) float32 depth of the surface behind the object
        (surface_depth(reference, cameras) or depth_behind(pre, target, cameras))
    find_occluders(scene, cameras, lifted, *, frame=None) -> Occluders (lifted with per_view=True:
        lifted Gaussians in front of the object that other views contradict; .doubtful, .message(paths))
    drop_occluders(lifted, occluders) -> LiftedTarget
    MaskLifter, TargetMaskRenderer    the device passes (weights / masks stay on the GPU)

frame: the scene's world frame (`r360gpu.io.frames.Frame`; None: the
cameras'): cameras are given in the bundle's world and moved into it
(`r360gpu.io.frames.in_frame`), depths come back in the cameras' units.
"""
from __future__ import annotations

from .device import MaskLifter
from .masks import MASK_SHARE, TargetMaskRenderer, label_scene, target_masks
from .occluders import Occluders, drop_occluders, find_occluders
from .orbit import keep_pose, orbit_cameras
from .residuals import (depth_behind, flagged_views, in_front, residuals, surface_depth, top_residuals,
                        write_residual_ply)
from .target import (MIN_SHARE, MIN_WEIGHT, Box, LiftedTarget, decide, lift_target, load_indices,
                     target_from_box, target_from_indices)

__all__ = [
    "MASK_SHARE", "MIN_SHARE", "MIN_WEIGHT", "Box", "LiftedTarget", "MaskLifter", "Occluders", "TargetMaskRenderer",
    "decide", "depth_behind", "drop_occluders", "find_occluders", "flagged_views", "in_front", "keep_pose", "label_scene", "lift_target",
    "load_indices", "orbit_cameras", "residuals", "surface_depth", "target_from_box", "target_from_indices",
    "target_masks", "top_residuals", "write_residual_ply",
]
