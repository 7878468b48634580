"""Where the RGB and depth of each evaluation view come from.

A reconstruction is either a splat scene, rendered here on the GPU at the
bundle's cameras, or a folder of renders made elsewhere (the protocol is
representation-agnostic).  Both give a :class:`ViewImages` per view:
``rgb`` float32 (H, W, 3) in [0, 1] (clipped), ``depth`` float32 (H, W)
camera-space z-distance with 0 = no coverage (expected or median depth, as
the bundle's options say), or ``None`` when a renders folder has no depth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass
class ViewImages:
    rgb: np.ndarray
    depth: np.ndarray | None
    alpha: np.ndarray | None = None


class SceneSource:
    """A splat scene kept on the device and rendered per camera."""

    kind = "scene"

    def __init__(self, path, *, ctx=None, background=(0.0, 0.0, 0.0), depth: str = "expected"):
        from ..io import load_gaussians
        from .pipeline import Renderer

        if depth not in ("expected", "median"):
            raise InputError(f"depth mode must be 'expected' or 'median', got {depth!r}")
        self.path = path
        self.depth_mode = depth
        self.gaussians = load_gaussians(path)
        self.renderer = Renderer(self.gaussians, ctx=ctx, background=tuple(float(c) for c in background))

    def images(self, view: str, camera) -> ViewImages:
        if camera is None:
            raise InputError(f"view {view!r} has no camera, so scene {self.path} cannot be rendered there")
        r = self.renderer.render(camera)
        depth = r.depth if self.depth_mode == "expected" else r.median_depth
        return ViewImages(np.clip(r.rgb, 0.0, 1.0), depth, r.alpha)

    def describe(self) -> dict:
        return {"kind": "scene", "path": str(self.path), "n_gaussians": int(self.gaussians.n),
                "sh_degree": int(self.gaussians.sh_degree), "depth": self.depth_mode}

    def release(self) -> None:
        self.renderer.release()


class RendersSource:
    """RGB and depth images made elsewhere (:class:`r360gpu.io.renders.RendersReader`)."""

    kind = "renders"

    def __init__(self, spec):
        from ..io.renders import RendersReader

        self.spec = spec
        self.reader = RendersReader(spec)

    def images(self, view: str, camera=None) -> ViewImages:
        rgb = self.reader.rgb(view)
        depth = self.reader.depth(view) if self.spec.depth_dir is not None else None
        return ViewImages(rgb, depth)

    def describe(self) -> dict:
        return {"kind": "renders", "path": str(self.spec.path), "depth_scale": float(self.spec.depth_scale)}

    def release(self) -> None:
        pass


def open_source(spec, *, ctx=None, background=(0.0, 0.0, 0.0), depth: str = "expected"):
    """A :class:`SceneSource` or :class:`RendersSource` for a bundle's ``SourceSpec``."""
    if spec.kind == "scene":
        return SceneSource(spec.path, ctx=ctx, background=background, depth=depth)
    if spec.kind == "renders":
        return RendersSource(spec)
    raise InputError(f"unknown source kind {spec.kind!r} for {spec.path}")
