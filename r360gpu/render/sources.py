"""Where the RGB and depth of each evaluation view come from.

A reconstruction is either a splat scene, rendered here on the GPU at the
bundle's cameras, or a folder of renders made elsewhere (the protocol is
representation-agnostic).  Both give a :class:`ViewImages` per view:
``rgb`` float32 (H, W, 3) in [0, 1] (clipped), ``depth`` float32 (H, W)
camera-space z-distance with 0 = no coverage (expected or median depth, as
the bundle's options say), or ``None`` when a renders folder has no depth.

Every source is a :class:`Source` (a protocol, like the probes' interface):
:class:`SceneSource`, :class:`RendersSource` and :class:`DeviceViewsSource`
here, or a caller's own object with the same members, which
:func:`open_source` takes as it is.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from ..errors import InputError


@dataclass
class ViewImages:
    rgb: np.ndarray
    depth: np.ndarray | None
    alpha: np.ndarray | None = None


@runtime_checkable
class Source(Protocol):
    """Where one reconstruction's images of each evaluation view come from.

    kind: ``"scene"`` (rendered here; the source then also has ``path``,
    ``renderer``, ``render_options``, ``background`` and ``frame``, see
    :class:`SceneSource`), ``"renders"`` (images read from a folder) or
    ``"device"`` (images on a GPU); what the pipeline decides by (e.g. only
    scenes have geometry to lift).
    images(view, camera): the view's :class:`ViewImages` (``camera`` the
    bundle's, None where the view has none).
    describe(): what goes into results.json as the source (includes ``kind``).
    bind(ctx): called once by :func:`open_source` with the run's context (None
    when the run has none yet): a source on the GPU takes it, or refuses one on
    another device; others ignore it.
    release(): free what the source holds (device buffers, open files).
    """

    kind: ClassVar[str]

    def images(self, view: str, camera) -> ViewImages: ...

    def describe(self) -> dict: ...

    def bind(self, ctx) -> None: ...

    def release(self) -> None: ...


class SceneSource:
    """A splat scene kept on the device and rendered per camera.

    ``scene``: a splat file path, or a :class:`~r360gpu.io.Gaussians` already in memory.
    ``render``: keywords of :class:`~r360gpu.render.conventions.RenderOptions`
    (a bundle source's ``render`` settings); absent keys keep the defaults.
    ``frame``: the world frame the Gaussians are in (:class:`~r360gpu.io.frames.Frame`,
    None: the cameras'): each camera is moved into it before rendering and the
    depth divided by its scale, so depth stays in the cameras' units.
    """

    kind = "scene"

    def __init__(self, scene, *, ctx=None, background=(0.0, 0.0, 0.0), depth: str = "expected",
                 render: dict | None = None, frame=None):
        from .conventions import RenderOptions

        from ..io import Gaussians, load_gaussians
        from .renderer import Renderer

        if depth not in ("expected", "median"):
            raise InputError(f"depth mode must be 'expected' or 'median', got {depth!r}")
        in_memory = isinstance(scene, Gaussians)
        self.in_memory = in_memory  # what it holds is known by its values only (pipeline.cache.fingerprint)
        self.path = "<in memory>" if in_memory else scene
        self.depth_mode = depth
        self.frame = frame
        self.background = tuple(float(c) for c in background)
        self.gaussians = scene if in_memory else load_gaussians(scene)
        self.render_options = RenderOptions(**(render or {}))
        try:
            self.renderer = Renderer(self.gaussians, ctx=ctx, background=self.background,
                                     options=self.render_options)
        except InputError as e:  # e.g. more Gaussians than one binding holds: name the file, say what to do
            if e.path is not None or in_memory:
                raise
            raise InputError(f"{e.problem}; prune or split the scene, or run on an adapter with larger storage "
                             f"bindings (`r360gpu doctor` lists this adapter's limits)", scene) from None

    def camera(self, camera):
        """The bundle's ``camera`` as this scene's Gaussians see it (`r360gpu.io.frames.in_frame`)."""
        from ..io.frames import in_frame

        return in_frame(self.frame, camera)

    def bind(self, ctx) -> None:
        """Nothing: the scene is rendered on the context it was opened with."""

    def images(self, view: str, camera) -> ViewImages:
        from ..io.frames import depth_in_cameras

        if camera is None:
            raise InputError(f"view {view!r} has no camera, so scene {self.path} cannot be rendered there")
        r = self.renderer.render(self.camera(camera))
        depth = r.depth if self.depth_mode == "expected" else r.median_depth
        return ViewImages(np.clip(r.rgb, 0.0, 1.0), depth_in_cameras(self.frame, depth), r.alpha)

    def describe(self) -> dict:
        from dataclasses import asdict

        out = {"kind": "scene", "path": str(self.path), "n_gaussians": int(self.gaussians.n),
               "sh_degree": int(self.gaussians.sh_degree), "depth": self.depth_mode,
               "render": asdict(self.render_options)}
        if self.frame is not None:
            out["frame"] = self.frame.describe()
        return out

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

    def bind(self, ctx) -> None:
        """Nothing: the images are read from files."""

    def release(self) -> None:
        pass


class DeviceViewsSource:
    """Renders another GPU pipeline already holds on the device, one per view.

    ``views`` maps a view name to a `DeviceRender`
    (this renderer's device output, or any buffer in that plane layout) or to
    a pair ``(rgb, depth)`` with ``rgb`` float (H, W, 3) in [0, 1] and
    ``depth`` a `DeviceDepth` or a
    float32 array.  Depth stays on the device: the geometric axis reads it
    there.  RGB comes to the host, because the probes run on the CPU.

    ``ctx``: the context of the device holding the buffers.  Without it, the
    source takes the context of the run it is scored in
    (`r360gpu.evaluate` binds its own, e.g. the one around
    ``device=``), so it need not be given twice.
    """

    kind = "device"

    def __init__(self, views, *, ctx=None, name: str = "device views"):
        self.views = dict(views)
        self._ctx = ctx
        self.name = name

    @property
    def ctx(self):
        if self._ctx is None:
            from ..gpu import get_context

            self._ctx = get_context()
        return self._ctx

    def bind(self, ctx) -> None:
        """Use ``ctx`` (the run's context) unless one was given; refuse a context on another device."""
        if ctx is None:
            return
        if self._ctx is None:
            self._ctx = ctx
        elif self._ctx.device is not ctx.device:
            raise InputError(f"{self.name}: its buffers' context is on another device than the run's; "
                             f"pass the same device (or context) to DeviceViewsSource and evaluate()")

    def images(self, view: str, camera=None) -> ViewImages:
        from ..gpu.context import DeviceDepth
        from .renderer import DeviceRender

        if view not in self.views:
            raise InputError(f"{self.name}: no render for view {view!r}")
        item = self.views[view]
        if isinstance(item, DeviceRender):
            h, w, stride = item.height, item.width, item.plane_stride
            planes = list(item.planes)
            rgb = np.stack([self.ctx.read(item.buffer, np.float32, h * w, planes.index(c) * stride * 4)
                            for c in ("r", "g", "b")], -1).reshape(h, w, 3)
            depth = DeviceDepth(item.buffer, h, w, offset=planes.index("depth") * stride * 4)
            return ViewImages(np.clip(rgb, 0.0, 1.0), depth)
        rgb, depth = item
        rgb = np.clip(np.asarray(rgb, np.float32), 0.0, 1.0)
        if depth is not None and not isinstance(depth, DeviceDepth):
            depth = np.asarray(depth, np.float32)
        return ViewImages(rgb, depth)

    def describe(self) -> dict:
        return {"kind": "device", "name": self.name, "views": len(self.views)}

    def release(self) -> None:
        pass


def host_depth(depth, ctx=None) -> np.ndarray | None:
    """A depth image on the host (reads a DeviceDepth back; arrays pass through)."""
    from ..gpu.context import DeviceDepth

    if isinstance(depth, DeviceDepth):
        from ..gpu import get_context

        ctx = ctx or get_context()
        return ctx.read(depth.buffer, np.float32, depth.height * depth.width, depth.offset).reshape(depth.height, depth.width)
    return depth


def frame_of(spec):
    """The world frame (`Frame`) of a bundle source's Gaussians: a scene
    spec's resolved ``frame``, an opened source's; None for the cameras' own frame (Gaussians in
    memory, renders, an unresolved draft)."""
    frame = getattr(spec, "frame", None)
    return frame if hasattr(frame, "camera") else None


def open_source(spec, *, ctx=None, background=(0.0, 0.0, 0.0), depth: str = "expected") -> Source:
    """A source for a bundle entry: a ``SourceSpec`` (splat file or renders
    folder), a :class:`~r360gpu.io.Gaussians` in memory, or a ready
    :class:`Source` (e.g. :class:`DeviceViewsSource`), bound to ``ctx``."""
    from ..io import Gaussians

    if isinstance(spec, Gaussians):
        return SceneSource(spec, ctx=ctx, background=background, depth=depth)
    if isinstance(spec, Source):
        spec.bind(ctx)
        return spec
    if hasattr(spec, "images"):  # meant as a ready source, but not one
        missing = [m for m in ("kind", "images", "describe", "bind", "release") if not hasattr(spec, m)]
        raise InputError(f"{type(spec).__name__} is not a source (r360gpu.render.sources.Source): "
                         f"it has no {', '.join(missing)}")
    if spec.kind == "scene":
        settings = getattr(spec, "render", None)
        return SceneSource(spec.path, ctx=ctx, background=background, depth=depth,
                           render=settings.given() if settings is not None else None, frame=frame_of(spec))
    if spec.kind == "renders":
        return RendersSource(spec)
    raise InputError(f"unknown source kind {spec.kind!r} for {spec.path}")
