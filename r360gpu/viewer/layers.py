"""The viewer's scenes: each bundle source as six float planes on the device.

A *layer* turns a camera into a :class:`PlaneImage`, the renderer's image
layout (:mod:`r360gpu.render.rasterize`: planes r, g, b, alpha, depth,
median_depth of ``stride`` floats each, row-major) in a wgpu buffer, so
overlays and composition read it without a host round trip.

* :class:`SplatLayer`: a Gaussian-splat source rendered by
  :class:`r360gpu.render.Renderer` at any camera.
* :class:`RendersLayer`: a folder of renderings made elsewhere; it has
  images only at the evaluation views (at their own resolution), so it
  returns None anywhere else.

Both keep the last few images keyed by the exact camera, so a still camera
costs no rendering.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from r360gpu.gpu.context import BufferRange, GpuContext
from r360gpu.gpu.context import DeviceDepth
from r360gpu.render.rasterize import PLANES, plane_stride

#: Plane index of each depth mode.
DEPTH_PLANE = {"expected": PLANES.index("depth"), "median": PLANES.index("median_depth")}
#: Images kept per layer (display at two resolutions plus the metric's).
CACHE_SIZE = 3


def camera_key(camera) -> tuple:
    """Hashable identity of everything that decides a rendering (:meth:`r360gpu.io.Camera.key`)."""
    return camera.key()


@dataclass
class PlaneImage:
    """A six-plane float32 image on the device (see the module docstring).

    ``depth_plane`` is the plane the geometric axis reads (4 expected, 5 median).
    """

    buffer: object
    width: int
    height: int
    stride: int
    depth_plane: int

    def window(self, plane: int, count: int = 1) -> BufferRange:
        """Binding window over ``count`` planes from ``plane``."""
        return BufferRange(self.buffer, plane * self.stride * 4, count * self.stride * 4)

    def rgb_window(self) -> BufferRange:
        return self.window(0, 3)

    def depth_window(self) -> BufferRange:
        return self.window(self.depth_plane)

    def device_depth(self) -> DeviceDepth:
        """The depth plane as the depth-change kernel's input."""
        return DeviceDepth(self.buffer, self.height, self.width, self.depth_plane * self.stride * 4)

    @property
    def size(self) -> tuple[int, int]:
        return (self.width, self.height)


class _Images:
    """An LRU of PlaneImages keyed by camera; evicted buffers are reused when big enough."""

    def __init__(self, ctx: GpuContext, label: str):
        self.ctx = ctx
        self.label = label
        self.items: OrderedDict = OrderedDict()
        self.free: list = []

    def get(self, key):
        img = self.items.get(key)
        if img is not None:
            self.items.move_to_end(key)
        return img

    def new_buffer(self, nbytes: int):
        for i, buf in enumerate(self.free):
            if buf.size >= nbytes:
                return self.free.pop(i)
        return self.ctx.buffer(nbytes, label=self.label)

    def put(self, key, img: PlaneImage) -> None:
        self.items[key] = img
        self.items.move_to_end(key)
        while len(self.items) > CACHE_SIZE:
            _, old = self.items.popitem(last=False)
            self.free.append(old.buffer)
        self.free = self.free[-CACHE_SIZE:]

    def clear(self) -> None:
        for img in self.items.values():
            self.free.append(img.buffer)
        self.items.clear()


class SplatLayer:
    """A splat-scene source, loaded on first use and rendered at any camera.

    ``source`` is a :class:`r360gpu.render.sources.SceneSource` (or anything
    with ``.renderer`` and ``.gaussians``); ``depth`` the bundle's depth mode.
    """

    kind = "scene"
    has_depth = True

    def __init__(self, name: str, open_source, *, ctx: GpuContext, depth: str = "expected"):
        self.name = name
        self._open = open_source
        self.ctx = ctx
        self.depth_plane = DEPTH_PLANE[depth]
        self.source = None
        self.images = _Images(ctx, f"viewer.{name}")
        self.render_seconds = 0.0  # wall time of the last rendering
        self.renders_done = 0  # renderings made so far (cache misses)

    @classmethod
    def from_gaussians(cls, name: str, gaussians, *, ctx: GpuContext, background=(0.0, 0.0, 0.0),
                       depth: str = "expected", frame=None, options=None) -> "SplatLayer":
        """A layer over in-memory Gaussians (e.g. the estimated target's subset of pre) in ``frame``
        (`r360gpu.io.frames.Frame`; None: the cameras') rendered with ``options``
        (`r360gpu.render.conventions.RenderOptions`), e.g. those of the scene they come from."""
        return cls(name, lambda: _GaussiansSource(gaussians, ctx, background, frame, options), ctx=ctx, depth=depth)

    def load(self):
        """The opened source (loads the splat file and uploads it on the first call)."""
        if self.source is None:
            self.source = self._open()
        return self.source

    @property
    def gaussians(self):
        return self.load().gaussians

    def available(self, view: str | None) -> bool:
        return True

    def image(self, camera, view: str | None = None) -> PlaneImage:
        """The rendering at ``camera`` (``view`` is ignored: a splat renders anywhere), seen in the
        source's frame (`r360gpu.io.frames.in_frame`), its depth planes in the cameras' units."""
        import time

        from r360gpu.io.frames import in_frame
        from r360gpu.render.sources import frame_of

        key = camera_key(camera)
        img = self.images.get(key)
        if img is not None:
            return img
        source = self.load()
        frame = frame_of(source)
        stride = plane_stride(camera.width, camera.height)
        buf = self.images.new_buffer(stride * len(PLANES) * 4)
        t0 = time.perf_counter()
        out = source.renderer.render_device(in_frame(frame, camera), image=buf)
        if frame is not None and frame.scale != 1.0:
            _depth_in_cameras(self.ctx, out, frame)
        self.render_seconds = time.perf_counter() - t0
        self.renders_done += 1
        img = PlaneImage(out.buffer, out.width, out.height, out.plane_stride, self.depth_plane)
        self.images.put(key, img)
        return img

    def host_rgb(self, view: str, camera) -> np.ndarray:
        """The view's RGB exactly as the evaluation gave it to the probes (float32 (H, W, 3) in [0, 1])."""
        return self.load().images(view, camera).rgb

    def release(self) -> None:
        self.images.clear()
        if self.source is not None:
            self.source.release()
            self.source = None


def _depth_in_cameras(ctx: GpuContext, out, frame) -> None:
    """Both depth planes of a device rendering in ``frame`` divided by its scale, in place (a round
    trip through the host, for scaled frames only: the scenes a trainer normalised)."""
    from r360gpu.io.frames import depth_in_cameras

    offset = PLANES.index("depth") * out.plane_stride * 4
    count = 2 * out.plane_stride  # depth and median_depth, adjacent
    ctx.write(out.buffer, depth_in_cameras(frame, ctx.read(out.buffer, np.float32, count, offset)), offset)


class _GaussiansSource:
    """The part of `r360gpu.render.sources.SceneSource` a layer uses, for in-memory Gaussians
    (``frame``, ``options``: theirs, as a scene source's; None: the cameras' frame, the defaults)."""

    def __init__(self, gaussians, ctx: GpuContext, background, frame=None, options=None):
        from r360gpu.render import Renderer

        self.gaussians = gaussians
        self.frame = frame
        self.renderer = Renderer(gaussians, ctx=ctx, background=tuple(float(c) for c in background),
                                 options=options)

    def release(self) -> None:
        self.renderer.release()


class RendersLayer:
    """A renders-folder source: images only at the evaluation views, at their own size.

    ``source`` is a :class:`r360gpu.render.sources.RendersSource` (``images(view)``
    gives rgb float32 (H, W, 3) and depth float32 (H, W) or None).  Without a
    depth folder the depth planes are 0 (no coverage), so depth overlays and
    the geometric axis show nothing for it.
    """

    kind = "renders"
    renders_done = 0  # uploads are not renderings: nothing to count for the resolution policy

    def __init__(self, name: str, open_source, *, ctx: GpuContext, views: list[str], has_depth: bool = True):
        self.name = name
        self.has_depth = bool(has_depth)
        self._sizes: dict[str, tuple[int, int]] = {}
        self._open = open_source
        self.ctx = ctx
        self.views = set(views)
        self.depth_plane = DEPTH_PLANE["expected"]
        self.source = None
        self.images = _Images(ctx, f"viewer.{name}")
        self.render_seconds = 0.0

    def load(self):
        if self.source is None:
            self.source = self._open()
        return self.source

    def available(self, view: str | None) -> bool:
        return view is not None and view in self.views

    def native_size(self, view: str) -> tuple[int, int]:
        """(width, height) of the view's rendering (read once per view)."""
        size = self._sizes.get(view)
        if size is None:
            rgb = self.load().images(view).rgb
            size = self._sizes[view] = (rgb.shape[1], rgb.shape[0])
        return size

    def image(self, camera, view: str | None = None) -> PlaneImage | None:
        """The view's rendering uploaded as planes, or None off the evaluation views."""
        if not self.available(view):
            return None
        key = ("view", view)
        img = self.images.get(key)
        if img is not None:
            return img
        vi = self.load().images(view)
        h, w = vi.rgb.shape[:2]
        stride = plane_stride(w, h)
        planes = np.zeros((len(PLANES), stride), np.float32)
        for c in range(3):
            planes[c, : w * h] = vi.rgb[..., c].reshape(-1)
        planes[PLANES.index("alpha"), : w * h] = 1.0
        if vi.depth is not None:
            d = np.asarray(vi.depth, np.float32).reshape(-1)
            planes[PLANES.index("depth"), : w * h] = d
            planes[PLANES.index("median_depth"), : w * h] = d
        buf = self.images.new_buffer(planes.nbytes)
        self.ctx.write(buf, planes.reshape(-1))
        img = PlaneImage(buf, w, h, stride, self.depth_plane)
        self.images.put(key, img)
        return img

    def host_rgb(self, view: str, camera=None) -> np.ndarray:
        return self.load().images(view).rgb

    def release(self) -> None:
        self.images.clear()
        self.source = None


def build_layers(bundle, ctx: GpuContext) -> dict:
    """One layer per bundle source, in the bundle's order (pre, reference, methods)."""
    from r360gpu.render.sources import open_source

    opts = bundle.options
    layers = {}
    for name, spec in bundle.sources().items():
        def opener(spec=spec):
            return open_source(spec, ctx=ctx, background=opts.background, depth=opts.depth)

        if spec.kind == "scene":
            layers[name] = SplatLayer(name, opener, ctx=ctx, depth=opts.depth)
        else:
            layers[name] = RendersLayer(name, opener, ctx=ctx, views=list(bundle.views),
                                        has_depth=spec.depth_dir is not None)
    return layers
