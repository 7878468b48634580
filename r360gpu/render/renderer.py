"""The render pipeline: project -> depth sort -> bin -> tile sort -> ranges -> rasterise.

Per view the host waits for the device once before the tile sort: the
projection, the depth sort and (when the whole image is rendered in one pass)
the per-Gaussian key counts of the whole image go out in one submission, and
one read returns the per-row key bounds (which plan the key windows) together
with the image's exact key count (which sizes the tile sort).  Only when the
keys need several windows (more than one storage binding of them) does each
further window wait for its own count.  Reading the image back to numpy
(rasterize.image_to_numpy: one read, or two on GPU adapters) is the only other
wait (none for :meth:`Renderer.render_device`).

The sorts are exact: the depth sort
orders the N Gaussians once by the float bits of their depth (32 bits;
positive floats order like their bits), binning emits each Gaussian's keys in
that order, and the tile sort is a stable radix sort of the K keys by the tile
id's ``ceil(log2(tiles))`` bits alone, so each tile's list is front to back
with ties in index order: the oracle's order (tests/test_render_recording.py).
One sort of 32-bit keys packing tile id and quantised depth (VkSplat, luma.gl)
would sort the K keys by 32 bits instead of N by 32 and K by the tile bits:
less work only where K < 2N up to 65,536 tiles (K is 6.4N for 1M Gaussians
at 1080p), and Gaussians whose depths share a bucket would blend in index
order (bench/bench_render_sort.py times both).

The last step, the pass over each tile's sorted list, is a
:class:`~r360gpu.render.tile_pass.TilePass`: the rasteriser for a render,
any other pass through :meth:`Renderer.run_pass` (target lifting).

Host recording is done once per frame shape, not per frame: wgpu cannot
replay a command buffer, but a frame records its passes with the bind groups
and uniform buffers of the frame before (`r360gpu.gpu.recording.FrameCache`;
uniforms rewritten in place where the camera or a key count changed them),
on the same scratch buffers and pipelines, so a frame of the same shape creates
no device objects.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Iterable, Iterator

import numpy as np

from ..errors import InputError
from ..gpu.context import GpuContext, get_context
from ..gpu.recording import FrameCache
from .binning import COUNT_WG, RANGES_WG, TileLists, TileWindow, plan_windows, record_counts, record_emit, record_ranges
from .conventions import NEAR_PLANE, NO_COVERAGE_ALPHA, TILE, RenderOptions
from .project import WG as PROJECT_WG, Projected, camera_arrays, project, tile_grid
from .rasterize import PLANES, Band, RasterPass, image_to_numpy, plane_stride, planes_to_numpy
from .scene import DeviceScene
from .scratch import Scratch
from .sort import host_sort, radix_sort
from .tile_pass import TilePass

#: Bits of the depth sort key (the float bits of the camera depth).
DEPTH_BITS = 32


@dataclass
class Render:
    """One rendered view (numpy).

    rgb (H, W, 3) float32 (not clipped above), depth (H, W) float32 expected
    camera-space depth, median_depth (H, W) float32, alpha (H, W) float32 in
    [0, 1].  Both depths are 0 where ``alpha < NO_COVERAGE_ALPHA``.
    """

    rgb: np.ndarray
    depth: np.ndarray
    median_depth: np.ndarray
    alpha: np.ndarray


@dataclass
class DeviceRender:
    """One rendered view left on the device.

    ``buffer`` holds six float32 planes of ``plane_stride`` floats each, in
    the order :data:`r360gpu.render.rasterize.PLANES` (r, g, b, alpha, depth,
    median_depth); plane ``i`` starts at byte ``4 * i * plane_stride`` and is
    row-major (``y * width + x``).  :meth:`to_numpy` reads it back.
    """

    buffer: object
    width: int
    height: int
    plane_stride: int
    planes: tuple = PLANES

    def to_numpy(self, ctx: GpuContext) -> Render:
        return Render(**image_to_numpy(ctx, self.buffer, self.width, self.height, self.plane_stride))


@dataclass
class RenderStats:
    """Work and (when timed) wall time per stage of the last view.

    times: seconds per stage ("project", "sort", "rasterize") when the
    renderer was created with ``timed=True`` (the host waits after each
    stage), else empty.  keys: duplicated (tile, Gaussian) keys; windows: key
    windows used; evaluated / blended: pixel-Gaussian pairs the rasteriser
    evaluated / blended (counted only when ``count_work=True``, else 0).
    """

    times: dict = field(default_factory=dict)
    keys: int = 0
    windows: int = 0
    evaluated: int = 0
    blended: int = 0


@dataclass
class Prepared:
    """A view projected and depth-sorted (:meth:`Renderer._prepare`): what each of its key windows reads.

    row_counts: (tiles_y,) key bounds per tile row; counted: the window of all the
    image's tiles with its exact key count and the per-Gaussian key offsets, when
    they were recorded with the projection (one-pass images), else None.
    """

    proj: Projected
    order: object
    row_counts: np.ndarray
    tiles_x: int
    counted: tuple | None


class Renderer:
    """Renders views of one scene that stays on the device.

    Parameters
    ----------
    scene : Gaussians (see :mod:`r360gpu.io.gaussians`)
    ctx : GpuContext, optional (default: :func:`r360gpu.gpu.get_context`)
    background : RGB in [0, 1] added with the remaining transmittance
    antialiased, near, no_coverage_alpha, principal_point : the conventions of
        :class:`~r360gpu.render.conventions.RenderOptions` (defaults: r360gpu's);
        ``options`` gives them as one object (keywords given override it)
    timed : wait after every stage and record its wall time in :attr:`stats`
    count_work : read back the rasteriser's work counters into :attr:`stats`

    ``frames`` is the `FrameCache` (`r360gpu.gpu.recording`) every view is recorded
    with; its ``counts`` say how many bind groups and uniform buffers were created
    and reused.
    """

    def __init__(self, scene, *, ctx: GpuContext | None = None, background=(0.0, 0.0, 0.0),
                 near: float | None = None, antialiased: bool | None = None, no_coverage_alpha: float | None = None,
                 principal_point: str | None = None, options: RenderOptions | None = None,
                 timed: bool = False, count_work: bool = False):
        self.ctx = ctx or get_context()
        bg = np.asarray(background, dtype=np.float64).reshape(-1)
        if bg.shape != (3,) or not np.isfinite(bg).all():
            raise InputError(f"background must be 3 finite numbers, got {background!r}")
        self.options = (options or RenderOptions()).replace(
            near=near, antialiased=antialiased, no_coverage_alpha=no_coverage_alpha, principal_point=principal_point)
        self.background = tuple(float(v) for v in bg)
        self.near = self.options.near
        self.timed = timed
        self.count_work = count_work
        self.scene = DeviceScene(self.ctx, scene)
        # Depth and tile sorts in numpy on CPU adapters: the same permutation for less CPU (sort.host_sort).
        self._host_sort = self.ctx.kernel_backend("sort") == "cpu"
        self.scratch = Scratch(self.ctx)
        self.frames = FrameCache()
        self._in_frame = False
        self.stats = RenderStats()
        limit = self.ctx.max_binding_bytes
        if self.scene.n * 16 > limit or self.scene.n > min(PROJECT_WG, COUNT_WG) * self.ctx.max_workgroups**2:
            raise InputError(
                f"scene has {self.scene.n} Gaussians; this device's {limit}-byte storage bindings "
                f"hold at most {limit // 16}"
            )

    # -- helpers ------------------------------------------------------------
    def _sync(self, buffer) -> None:
        self.ctx.read(buffer, np.uint32, 1)

    def _mark(self, stage: str, t0: float, buffer) -> float:
        if not self.timed:
            return t0
        self._sync(buffer)
        now = time.perf_counter()
        self.stats.times[stage] = self.stats.times.get(stage, 0.0) + (now - t0)
        return now

    @contextmanager
    def _frame(self):
        """Record one frame with :attr:`frames` (what the frame before created is reused)."""
        if self._in_frame:
            yield
            return
        self.frames.begin_frame()
        self._in_frame = True
        try:
            with self.ctx.recording(self.frames):
                yield
        finally:
            self._in_frame = False

    # -- one view -----------------------------------------------------------
    def render_device(self, camera, image=None) -> DeviceRender:
        """Render ``camera`` into a device buffer (a new one unless ``image`` is given).

        The image must fit one buffer whose planes each fit one storage
        binding (see :meth:`band_rows`); :meth:`render` has no such limit.
        """
        with self._frame():
            return self._render_device(camera, image)

    def _render_device(self, camera, image) -> DeviceRender:
        cam = self._camera(camera)
        width, height = cam["width"], cam["height"]
        if self.band_rows(cam) < height:
            raise InputError(f"{cam['name']}: a {width}x{height} image does not fit one device buffer "
                             f"({self.ctx.max_binding_bytes}-byte bindings); render it to host memory "
                             "(Renderer.render, output='numpy'), which renders it in row bands")
        stride = plane_stride(width, height)
        if image is None:
            image = self.ctx.buffer(stride * len(PLANES) * 4, label="render.image")
        prep, t0 = self._prepare(cam, whole=True)
        self._render_rows(prep, cam, (0, len(prep.row_counts)), self._raster(Band(image, stride, 0)), t0)
        return DeviceRender(buffer=image, width=width, height=height, plane_stride=stride)

    def run_pass(self, camera, tile_pass: TilePass) -> None:
        """Project and sort ``camera``'s view and record ``tile_pass`` over all of its tiles.

        The extension point (:mod:`r360gpu.render.tile_pass`): every step but
        the pass is the render's own (same projection, sorts and tile lists,
        so a pass sees each pixel's Gaussians in the order the render blends
        them).  The pass is submitted; nothing is read back.
        """
        with self._frame():
            cam = self._camera(camera)
            prep, t0 = self._prepare(cam, whole=True)
            self._render_rows(prep, cam, (0, len(prep.row_counts)), tile_pass, t0)

    def _raster(self, band: Band) -> RasterPass:
        return RasterPass(band, self.background, self.options.no_coverage_alpha, self.scratch)

    def band_rows(self, camera) -> int:
        """Pixel rows rendered per pass: the whole height when the image fits, else whole tile rows.

        A pass writes six planes into one buffer (at most the device's
        max-buffer-size), each bound as one storage binding.  InputError when
        not even one row of tiles fits.
        """
        cam = camera if isinstance(camera, dict) else self._camera(camera)
        width, height = cam["width"], cam["height"]
        ctx = self.ctx
        per_plane = min(ctx.max_binding_bytes, int(ctx.limits.get("max-buffer-size", 1 << 62)) // len(PLANES))
        if plane_stride(width, height) * 4 <= per_plane:
            return height
        rows = (per_plane // 4 // width) // TILE * TILE
        while rows >= TILE and plane_stride(width, rows) * 4 > per_plane:
            rows -= TILE
        if rows < TILE:
            raise InputError(f"{cam['name']}: a {width}x{height} image is too wide for this device: one row of "
                             f"{TILE}-pixel tiles ({width}x{TILE} pixels) exceeds a {per_plane}-byte storage binding")
        return rows

    def _prepare(self, cam: dict, whole: bool):
        """Project and depth-sort every Gaussian for ``cam``.

        ``whole``: the image is rendered in one pass, so the key counts of
        the window of all its tiles are recorded in the same submission and
        read with the row bounds.  Returns (:class:`Prepared`, t0).
        """
        ctx, scratch, n = self.ctx, self.scratch, self.scene.n
        gx, gy = tile_grid(cam["width"], cam["height"])
        self.stats = RenderStats()
        t0 = time.perf_counter()

        enc = ctx.encoder()
        proj = project(ctx, enc, self.scene, cam, (gx, gy), self.near, scratch, self.options.antialiased)
        if self.timed or self._host_sort:
            ctx.submit(enc)
            t0 = self._mark("project", t0, proj.row_counts)
            enc = ctx.encoder()
        if self._host_sort:
            _, order = host_sort(ctx, proj.depth_key, proj.idx, n, DEPTH_BITS)
        else:
            _, order = radix_sort(ctx, enc, proj.depth_key, proj.idx, n, DEPTH_BITS, scratch, "depth")
        counted = None
        if whole and self._one_dispatch(gx * gy):
            window = TileWindow(0, gx * gy, None)
            offsets, total = record_counts(ctx, enc, proj, order, n, gx, window, scratch)
            # the total rides behind the row bounds, so one read returns both
            enc.copy_buffer_to_buffer(total.buffer, total.offset, proj.row_counts, gy * 4, 4)
            counted = (window, offsets)
        ctx.submit(enc)
        got = ctx.read(proj.row_counts, np.uint32, gy + 1).astype(np.int64)
        row_counts = got[:gy]
        if counted is not None:
            counted = (TileWindow(0, gx * gy, int(got[gy])), counted[1])
        t0 = self._mark("sort", t0, proj.row_counts)
        return Prepared(proj, order, row_counts, gx, counted), t0

    def _render_rows(self, prep: Prepared, cam: dict, rows: tuple[int, int], tile_pass: TilePass, t0: float) -> None:
        """Record ``tile_pass`` over tile rows [row0, row1) = ``rows``.  ``prep.counted`` is used when
        the plan is that one window."""
        row0, row1 = rows
        gx, counted = prep.tiles_x, prep.counted
        pending = [TileWindow(w.begin + row0 * gx, w.end + row0 * gx, w.keys)
                   for w in plan_windows(prep.row_counts[row0:row1], gx, self._key_capacity())]
        pending.reverse()
        while pending:
            window = pending.pop()
            if window.end <= window.begin:
                continue
            use = counted if counted is not None and (window.begin, window.end) == (
                counted[0].begin, counted[0].end) else None
            window = self._render_window(prep, window, cam, tile_pass, t0, use)
            if isinstance(window, list):
                pending.extend(reversed(window))
            t0 = time.perf_counter()

    def _camera(self, camera) -> dict:
        cam = camera_arrays(camera)
        if self.options.principal_point == "centre":
            cam["cx"], cam["cy"] = 0.5 * cam["width"], 0.5 * cam["height"]
        return cam

    def _key_capacity(self) -> int:
        """Most keys one window may hold: one binding, and one dispatch of one thread per key."""
        return min(self.ctx.max_binding_bytes // 4, RANGES_WG * self.ctx.max_workgroups**2)

    def _one_dispatch(self, num_tiles: int) -> bool:
        """Whether a window of ``num_tiles`` tiles fits one rasteriser dispatch (one workgroup per
        tile) and its ranges (8 bytes per tile) one binding."""
        return num_tiles <= self.ctx.max_workgroups**2 and num_tiles * 8 <= self.ctx.max_binding_bytes

    def _render_window(self, prep: Prepared, window: TileWindow, cam: dict, tile_pass: TilePass, t0: float,
                       counted=None):
        """Bin and sort one key window and record ``tile_pass`` over it; returns halves if it had to be split.

        ``counted``: (this window with its exact key count, its offsets) when already counted."""
        ctx, scratch, n = self.ctx, self.scratch, self.scene.n
        proj, order, gx = prep.proj, prep.order, prep.tiles_x
        num_tiles = window.end - window.begin
        if not self._one_dispatch(num_tiles):
            mid = (window.begin + window.end) // 2
            return [TileWindow(window.begin, mid, None), TileWindow(mid, window.end, None)]
        if counted is not None:
            offsets, keys = counted[1], counted[0].keys
        else:
            enc = ctx.encoder()
            offsets, total = record_counts(ctx, enc, proj, order, n, gx, window, scratch)
            ctx.submit(enc)
            keys = int(ctx.read(total.buffer, np.uint32, 1, total.offset)[0])
        if keys > self._key_capacity():
            mid = (window.begin + window.end) // 2
            return [TileWindow(window.begin, mid, None), TileWindow(mid, window.end, None)]
        window = TileWindow(window.begin, window.end, keys)
        enc = ctx.encoder()
        k = window.keys
        self.stats.keys += k
        self.stats.windows += 1
        keys = vals = scratch.get("bin.keys", 4)
        if k > 0:
            keys, vals = record_emit(ctx, enc, proj, order, offsets, n, gx, window, scratch)
            bits = (num_tiles - 1).bit_length()  # 0 for one tile: already in order
            if bits and self._host_sort:
                ctx.submit(enc)
                keys, vals = host_sort(ctx, keys, vals, k, bits)
                enc = ctx.encoder()
            else:
                keys, vals = radix_sort(ctx, enc, keys, vals, k, bits, scratch, "tiles")
        ranges = record_ranges(ctx, enc, keys, k, num_tiles, scratch)
        ctx.submit(enc)
        t0 = self._mark("sort", t0, ranges.buffer)
        enc = ctx.encoder()
        tile_pass.record(ctx, enc, TileLists(proj, n, ranges, vals, k, gx, window), cam)
        ctx.submit(enc)
        self._mark("rasterize", t0, ranges.buffer)
        if self.count_work and isinstance(tile_pass, RasterPass):
            work = tile_pass.work
            counts = ctx.read(work.buffer, np.uint32, 2 * num_tiles).reshape(-1, 2).astype(np.int64)
            self.stats.evaluated += int(counts[:, 0].sum())
            self.stats.blended += int(counts[:, 1].sum())
        return window

    def render(self, camera) -> Render:
        """Render ``camera`` and read the result back as numpy arrays.

        An image beyond one device buffer renders in row bands (:meth:`band_rows`),
        pixel for pixel as one pass would: every band uses the same projection
        and depth order, and a tile's pixels depend on nothing outside it.
        """
        with self._frame():
            return self._render(camera)

    def _render(self, camera) -> Render:
        cam = self._camera(camera)
        width, height = cam["width"], cam["height"]
        rows = self.band_rows(cam)
        if rows >= height:
            image = self.scratch.get("render.image", plane_stride(width, height) * len(PLANES) * 4)
            return self._render_device(camera, image).to_numpy(self.ctx)
        out = _host_image(cam)
        stride = plane_stride(width, rows)
        image = self.scratch.get("render.image", stride * len(PLANES) * 4)
        prep, t0 = self._prepare(cam, whole=False)
        for y0 in range(0, height, rows):
            h = min(rows, height - y0)
            self._render_rows(prep, cam, (y0 // TILE, -(-(y0 + h) // TILE)), self._raster(Band(image, stride, y0)), t0)
            planes = planes_to_numpy(self.ctx, image, width, h, stride)
            for c, name in enumerate("rgb"):
                out.rgb[y0:y0 + h, :, c] = planes[name]
            for name in ("alpha", "depth", "median_depth"):
                getattr(out, name)[y0:y0 + h] = planes[name]
            t0 = time.perf_counter()
        return out

    def release(self) -> None:
        """Free the scene and every intermediate buffer now."""
        self.scene.release()
        self.frames.clear()
        self.scratch.release()


def _host_image(cam: dict) -> Render:
    """Empty host arrays for a view, or InputError when this machine's memory cannot hold them."""
    width, height = cam["width"], cam["height"]
    need = width * height * 4 * (3 + 3)
    avail = _available_memory()
    if avail is not None and need > avail:
        raise InputError(f"{cam['name']}: a {width}x{height} render needs {need / 2**30:.1f} GiB of host memory; "
                         f"{avail / 2**30:.1f} GiB are available")
    try:
        return Render(rgb=np.empty((height, width, 3), np.float32), depth=np.empty((height, width), np.float32),
                      median_depth=np.empty((height, width), np.float32), alpha=np.empty((height, width), np.float32))
    except MemoryError:
        raise InputError(f"{cam['name']}: not enough host memory for a {width}x{height} render "
                         f"({need / 2**30:.1f} GiB)") from None


def _available_memory() -> int | None:
    """Bytes of memory available to new allocations (Linux MemAvailable), None when unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def render(scene, camera, *, ctx: GpuContext | None = None, background=(0.0, 0.0, 0.0), output: str = "numpy",
           near: float = NEAR_PLANE, antialiased: bool = False, no_coverage_alpha: float = NO_COVERAGE_ALPHA,
           principal_point: str = "camera"):
    """Render one view of ``scene`` (a `Gaussians`).

    camera: a `Camera` (world-to-camera R, t; fx, fy,
    cx, cy; width, height).  output: "numpy" -> `Render`; "device" ->
    `DeviceRender` (buffers stay on ``ctx``'s device).  near,
    antialiased, no_coverage_alpha, principal_point: the conventions of
    `RenderOptions`.
    """
    if output not in ("numpy", "device"):
        raise InputError(f"output must be 'numpy' or 'device', got {output!r}")
    renderer = Renderer(scene, ctx=ctx, background=background, near=near, antialiased=antialiased,
                        no_coverage_alpha=no_coverage_alpha, principal_point=principal_point)
    try:
        if output == "device":
            return renderer.render_device(camera)
        return renderer.render(camera)
    finally:
        renderer.release()


def render_views(scene, cameras: Iterable, *, ctx: GpuContext | None = None, background=(0.0, 0.0, 0.0),
                 output: str = "numpy", near: float = NEAR_PLANE, antialiased: bool = False,
                 no_coverage_alpha: float = NO_COVERAGE_ALPHA, principal_point: str = "camera",
                 progress: bool = False) -> Iterator:
    """Render many views of one scene, uploading it once; yields one result per camera.

    Results and options as :func:`render`.  ``progress`` shows a tqdm progress bar.
    """
    if output not in ("numpy", "device"):
        raise InputError(f"output must be 'numpy' or 'device', got {output!r}")
    renderer = Renderer(scene, ctx=ctx, background=background, near=near, antialiased=antialiased,
                        no_coverage_alpha=no_coverage_alpha, principal_point=principal_point)
    cams = cameras
    if progress:
        from tqdm import tqdm

        cams = tqdm(cameras, desc="render", unit="view")
    try:
        for camera in cams:
            yield renderer.render_device(camera) if output == "device" else renderer.render(camera)
    finally:
        renderer.release()
