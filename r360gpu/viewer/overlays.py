"""GPU overlays of one panel (host side of ``shaders/viewer_overlay.wgsl``).

The overlay pass turns a scene's :class:`~r360gpu.viewer.layers.PlaneImage` into the
panel's picture, packed rgba8 (one u32 per pixel, row-major, sRGB values as
the renderer's colours are): the scene's colour clipped to [0, 1], then, each
mixed in with ``opacity``,

* depth: the scene's depth through the colour map over ``depth_range``
  (pixels without coverage keep their colour);
* |dD| heat map: ``|D_pre - D_scene|`` (0 where either has no coverage,
  the geometric axis' rule) through the colour map over ``heat_range``;
  pixels at or below the GHT threshold are mixed with 0.35 x opacity;
* changed mask: pixels whose |dD| bin lies above the GHT split
  (:mod:`r360gpu.kernels.depth_change` binning, so the overlay agrees pixel
  for pixel with the geometric axis at the same resolution) in magenta;
* probe masks: each instance in its own colour (0.6 x opacity);
* target outline: the boundary of the target mask (pixels inside the mask
  with an outside pixel ``outline_px`` away along x or y), opaque yellow.

:func:`overlay_reference` is the numpy twin of the depth, |dD|, changed and
outline overlays, used by the tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from r360gpu.gpu.context import GpuContext
from r360gpu.gpu.shaders import workgroup_size, workgroup_threads

from . import colormaps
from .layers import PlaneImage

SHADER = "viewer_overlay"
#: The WGSL names of the resources the calls here bind, by position (checked at pipeline creation).
BINDINGS = ("P", "scene_rgb", "scene_depth", "pre_depth", "mask_words", "probe_ids", "cmap", "out_rgba", "stats")
_TILE_XY = workgroup_size(SHADER, "overlay")  # pixels one overlay workgroup covers
HEAT_BELOW = 0.35
CHANGED_RGB = (1.0, 0.1, 0.75)
OUTLINE_RGB = (1.0, 0.86, 0.0)
_BITS = {"depth": 0, "delta": 1, "changed": 2, "outline": 3, "probes": 4, "pre": 5, "mask": 6, "probe_ids": 7}


@dataclass(frozen=True)
class DeltaStats:
    """Histogram binning and GHT split of |dD| for one (pre, scene) pair at one resolution.

    lo, hi: range of dD; scale: float32 256 / (hi - lo) (0 when empty);
    split: GHT split in bins (changed = bin > split); threshold: the split in
    depth units (xi_depth).
    """

    lo: float
    hi: float
    scale: float
    split: float
    threshold: float


@dataclass
class OverlaySettings:
    """What to draw on one panel (from :class:`r360gpu.viewer.state.Overlays` plus live data).

    depth_range / heat_range: colour-map ranges in scene units.
    delta: the pair's :class:`DeltaStats`, or None when no pre depth is available.
    """

    depth: bool = False
    delta_heat: bool = False
    changed: bool = False
    outline: bool = False
    probes: bool = False
    colormap: str = "turbo"
    opacity: float = 0.6
    depth_range: tuple[float, float] = (0.0, 1.0)
    heat_range: tuple[float, float] = (0.0, 1.0)
    delta: DeltaStats | None = None
    outline_px: int = 1


def pack_mask(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool -> flat little-endian bit words (uint32), bit ``i % 32`` of word ``i // 32`` = pixel i."""
    bits = np.packbits(np.asarray(mask, bool).reshape(-1), bitorder="little")
    words = np.zeros(-(-bits.size // 4) * 4, np.uint8)
    words[: bits.size] = bits
    return words.view(np.uint32)


class OverlayPass:
    """Records overlay dispatches on a :class:`GpuContext` (pipelines from its cache)."""

    def __init__(self, ctx: GpuContext):
        self.ctx = ctx
        self._cmaps: dict[str, object] = {}
        self._dummy = ctx.buffer(np.zeros(64, np.uint32), label="viewer.dummy")

    def cmap_buffer(self, name: str):
        buf = self._cmaps.get(name)
        if buf is None:
            buf = self._cmaps[name] = self.ctx.buffer(np.ascontiguousarray(colormaps.lut(name)), label=f"cmap.{name}")
        return buf

    def upload_mask(self, mask: np.ndarray):
        """A device buffer with the bit-packed (H, W) bool mask."""
        return self.ctx.buffer(pack_mask(mask), label="viewer.mask")

    def upload_ids(self, ids: np.ndarray):
        """A device buffer with (H, W) per-pixel probe instance ids (uint32, 0 = none)."""
        return self.ctx.buffer(np.ascontiguousarray(ids, np.uint32).reshape(-1), label="viewer.probe_ids")

    def output_buffer(self, width: int, height: int, previous=None):
        """A packed-rgba8 picture buffer for ``width x height`` (``previous`` reused when big enough)."""
        need = max(4, width * height * 4)
        if previous is not None and previous.size >= need:
            return previous
        return self.ctx.buffer(need, label="viewer.picture")

    def record(self, enc, scene: PlaneImage, settings: OverlaySettings, out, *, pre: PlaneImage | None = None,
               mask=None, probe_ids=None) -> None:
        """Record the overlay pass of one panel into ``out`` (see :meth:`output_buffer`).

        ``pre``: pre's image at the same size (needed by the |dD| overlays);
        ``mask`` / ``probe_ids``: buffers from :meth:`upload_mask` / :meth:`upload_ids`
        at the same size, or None.
        """
        ctx = self.ctx
        w, h = scene.width, scene.height
        flags = 0
        for name, on in (("depth", settings.depth), ("delta", settings.delta_heat), ("changed", settings.changed),
                         ("outline", settings.outline), ("probes", settings.probes)):
            if on:
                flags |= 1 << _BITS[name]
        use_pre = pre is not None and settings.delta is not None and (pre.width, pre.height) == (w, h)
        if use_pre:
            flags |= 1 << _BITS["pre"]
        if mask is not None:
            flags |= 1 << _BITS["mask"]
        if probe_ids is not None:
            flags |= 1 << _BITS["probe_ids"]
        d = settings.delta or DeltaStats(0.0, 0.0, 0.0, 255.0, 0.0)
        params = ctx.uniform(
            int(w), int(h), int(scene.stride), int(flags), int(max(1, settings.outline_px)), 0, 0, 0,
            float(settings.depth_range[0]), float(settings.depth_range[1]),
            float(settings.heat_range[0]), float(settings.heat_range[1]),
            float(np.float32(d.lo)), float(np.float32(d.scale)), float(d.split), float(settings.opacity),
        )
        resources = [
            params, scene.rgb_window(), scene.depth_window(),
            pre.depth_window() if use_pre else scene.depth_window(),
            mask if mask is not None else self._dummy,
            probe_ids if probe_ids is not None else self._dummy,
            self.cmap_buffer(settings.colormap), out,
        ]
        ctx.dispatch(enc, ctx.pipeline(SHADER, "overlay", bindings=BINDINGS), resources,
                     (math.ceil(w / _TILE_XY[0]), math.ceil(h / _TILE_XY[1]), 1))

    def depth_range(self, image: PlaneImage) -> tuple[float, float] | None:
        """(min, max) of the valid depths of ``image`` (waits for the device), None without coverage."""
        ctx = self.ctx
        stats = ctx.buffer(np.array([0xFFFFFFFF, 0, 0, 0], np.uint32), label="viewer.depth_stats")
        params = ctx.uniform(int(image.width), int(image.height), int(image.stride), 0, 1, 0, 0, 0,
                             0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        n = image.width * image.height
        ctx.run(ctx.pipeline(SHADER, "depth_range", bindings=BINDINGS),
                [params, None, image.depth_window(), None, None, None, None, None, stats], math.ceil(n / workgroup_threads(SHADER, "depth_range")))
        lo_bits, hi_bits = ctx.read(stats, np.uint32, 2)
        if lo_bits == 0xFFFFFFFF:
            return None
        return float(np.uint32(lo_bits).view(np.float32)), float(np.uint32(hi_bits).view(np.float32))


def read_picture(ctx: GpuContext, out, width: int, height: int) -> np.ndarray:
    """A packed picture buffer as (H, W, 4) uint8 RGBA."""
    return ctx.read(out, np.uint8, width * height * 4).reshape(height, width, 4)


def overlay_reference(rgb: np.ndarray, depth: np.ndarray, settings: OverlaySettings, *, pre_depth=None,
                      mask=None, probe_ids=None) -> np.ndarray:
    """numpy twin of the overlay pass: (H, W, 3) float32 colours in [0, 1] before 8-bit packing."""
    c = np.clip(np.asarray(rgb, np.float32), 0.0, 1.0).copy()
    a = np.float32(settings.opacity)
    d = np.asarray(depth, np.float32)

    def valid(x):
        return (x > 0) & np.isfinite(x)

    def norm(x, lo, hi):
        lo, hi = np.float32(lo), np.float32(hi)
        return (x - lo) / (hi - lo) if hi > lo else np.zeros_like(x)

    def mix(base, col, w):
        w = np.asarray(w, np.float32)
        if w.ndim == 2:
            w = w[..., None]
        return base * (1 - w) + col * w

    if settings.depth:
        v = valid(d)
        c[v] = mix(c[v], colormaps.apply(settings.colormap, norm(d[v], *settings.depth_range)), a)
    if pre_depth is not None and settings.delta is not None and (settings.delta_heat or settings.changed):
        p = np.asarray(pre_depth, np.float32)
        both = valid(d) & valid(p)
        dd = np.where(both, np.abs(p - d), np.float32(0)).astype(np.float32)
        st = settings.delta
        b = np.clip(np.floor((dd - np.float32(st.lo)) * np.float32(st.scale)), 0, 255)
        changed = b > st.split
        if settings.delta_heat:
            w = np.where(changed, a, a * np.float32(HEAT_BELOW))
            c = mix(c, colormaps.apply(settings.colormap, norm(dd, *settings.heat_range)), w)
        if settings.changed:
            c[changed] = mix(c[changed], np.asarray(CHANGED_RGB, np.float32), a)
    if settings.outline and mask is not None:
        m = np.asarray(mask, bool)
        r = max(1, settings.outline_px)
        pad = np.pad(m, r, constant_values=False)
        h, w = m.shape
        keep = (pad[r:r + h, 0:w] & pad[r:r + h, 2 * r:2 * r + w] & pad[0:h, r:r + w] & pad[2 * r:2 * r + h, r:r + w])
        edge = m & ~keep
        c[edge] = np.asarray(OUTLINE_RGB, np.float32)
    return c
