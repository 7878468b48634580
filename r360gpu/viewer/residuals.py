"""The residual highlight (key O): a method's Gaussians coloured by their ``residual``.

``score --residuals`` writes ``residuals/SCENE/METHOD.ply``, the method's
Gaussians with a float ``residual`` vertex property
(:mod:`r360gpu.lift.residuals`).  With the highlight on, each shown splat
scene that has residuals is drawn as a copy of its Gaussians recoloured by
them (geometry, opacity and so depth unchanged): a Gaussian of residual r
gets ``(1 - r) * grey + r * heat(r)``, grey its own colour's luminance
dimmed to :data:`DIM`, heat the ``inferno`` map's bright half, so the
Gaussians behind the evidence glow over a grey scene.  View-dependent colour
is dropped.

Where the residuals come from, first found: the scene's own splat file when
it has a ``residual`` property (a residuals PLY opened as a method), else the
results file's ``residuals`` entry of the method (``view --results``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import colormaps

#: Grey level range of the Gaussians without residual: luminance x DIM + (1 - DIM) / 4.
DIM = 0.5
#: The heat of residual r is the inferno map at HEAT_FROM + (1 - HEAT_FROM) r (its bright half).
HEAT_FROM = 0.5


def highlight_colours(rgb: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """(N, 3) float32 display colours of Gaussians of colour ``rgb`` (N, 3) and ``residual`` (N,)."""
    r = np.clip(np.nan_to_num(np.asarray(residual, np.float64), nan=0.0), 0.0, 1.0)[:, None]
    luma = np.asarray(rgb, np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    grey = np.repeat((np.clip(luma, 0.0, 1.0) * DIM + (1.0 - DIM) / 4)[:, None], 3, axis=1)
    heat = colormaps.apply("inferno", HEAT_FROM + (1.0 - HEAT_FROM) * r[:, 0]).astype(np.float64)
    return ((1.0 - r) * grey + r * heat).astype(np.float32)


def highlighted(gaussians, residual: np.ndarray):
    """A copy of ``gaussians`` coloured by :func:`highlight_colours` (degree-0 colour only)."""
    from r360gpu.io import Gaussians
    from r360gpu.io.sh import C0

    base = np.asarray(gaussians.sh, np.float64)[:, 0, :] * C0 + 0.5  # the degree-0 colour
    sh = ((highlight_colours(base, residual) - 0.5) / C0).reshape(gaussians.n, 1, 3)
    return Gaussians(gaussians.means, gaussians.scales, gaussians.quats, gaussians.opacities, sh)


def ply_residual(path) -> np.ndarray | None:
    """The ``residual`` vertex property of a PLY file, or None (not a PLY, no such property)."""
    from r360gpu.io.ply import read_ply

    path = Path(path)
    if path.suffix.lower() != ".ply" or not path.is_file():
        return None
    vert = read_ply(path).arrays.get("vertex")
    if vert is None or "residual" not in (vert.dtype.names or ()):
        return None
    return np.asarray(vert["residual"], np.float64)


class ResidualHighlight:
    """Per scene of one :class:`r360gpu.viewer.app.ViewerApp`: its residuals and highlighted layer."""

    def __init__(self, app):
        self.app = app
        self._values: dict = {}
        self._layers: dict = {}

    def values(self, name: str) -> np.ndarray | None:
        """(N,) residuals of scene ``name`` (None: it has none, or they do not match its Gaussians)."""
        if name in self._values:
            return self._values[name]
        app, r = self.app, None
        layer = app.layers.get(name)
        if layer is not None and layer.kind == "scene":
            spec = app.bundle.sources().get(name)
            r = ply_residual(spec.path) if spec is not None else None
            results = app.results
            if r is None and results is not None and name in getattr(results, "residuals", {}):
                r = ply_residual(results.residuals[name])
            g = layer.gaussians
            if r is not None and len(r) == g.n_file and g.n_file != g.n:  # one residual per row of the file
                r = r[g.rows]
            if r is not None and len(r) != layer.gaussians.n:
                app.notify(f"{name}: {len(r)} residuals for {layer.gaussians.n} Gaussians; not shown")
                r = None
        self._values[name] = r
        return r

    def available(self, name: str) -> bool:
        return self.values(name) is not None

    def layer(self, name: str):
        """The highlighted :class:`~r360gpu.viewer.layers.SplatLayer` of scene ``name``, or None."""
        from .layers import DEPTH_PLANE, SplatLayer

        if name not in self._layers:
            r = self.values(name)
            if r is None:
                self._layers[name] = None
            else:
                base = self.app.layers[name]
                depth = next(k for k, v in DEPTH_PLANE.items() if v == base.depth_plane)
                self._layers[name] = SplatLayer.from_gaussians(
                    f"{name} residuals", highlighted(base.gaussians, r), ctx=self.app.ctx,
                    background=self.app.bundle.options.background, depth=depth)
        return self._layers[name]

    def release(self) -> None:
        for layer in self._layers.values():
            if layer is not None:
                layer.release()
        self._layers.clear()
