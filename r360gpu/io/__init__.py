"""Loaders: Gaussian-splat scenes, cameras, masks (the first stage of the data flow).

Data types (each module defines its conventions once):

* `Gaussians` (`.gaussians`): means, linear scales, (w, x, y, z)
  unit quaternions, sigmoid'd opacities, SH coefficients (N, K, 3); the SH
  basis and colour rule are in `.sh`.
* `Camera` (`.camera`): OpenCV world-to-camera pinhole camera,
  pixel coordinates with the top-left pixel's centre at (0.5, 0.5).

Entry points: `load_gaussians`, `load_cameras`, `load_mask`;
one module per file format with its reader and writer.
"""
from __future__ import annotations

from .camera import Camera
from .cameras_json import load_cameras_json, save_cameras_json
from .colmap import load_colmap, save_colmap
from .compressed_ply import load_compressed_ply, save_compressed_ply
from .gaussians import Gaussians, build_gaussians, random_gaussians
from .inria_ply import load_inria_ply, save_ply
from .load import load_cameras, load_gaussians
from .masks import load_mask
from .splat import load_splat, save_splat
from .transforms_json import load_transforms_json, save_transforms_json

__all__ = [
    "Camera", "Gaussians", "build_gaussians", "random_gaussians",
    "load_gaussians", "load_cameras", "load_mask",
    "load_inria_ply", "save_ply", "load_compressed_ply", "save_compressed_ply",
    "load_splat", "save_splat",
    "load_colmap", "save_colmap", "load_cameras_json", "save_cameras_json",
    "load_transforms_json", "save_transforms_json",
]
