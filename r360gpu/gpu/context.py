"""The GPU context: one wgpu device plus cached shaders and compute pipelines.

Callers never write wgpu boilerplate: they ask the context for a pipeline by
shader file name, for buffers, and to dispatch passes.

Device limits that shape every kernel wrapper:

``max_binding_bytes``
    the largest storage-buffer binding (lavapipe: 128 MiB).  Wrappers split
    their inputs so that no binding exceeds it.
``max_workgroups``
    the most workgroups per dispatch dimension (65,535).  :meth:`GpuContext.grid`
    folds a 1-D workgroup count into x and y; shaders recover the linear id
    as ``wid.x + wid.y * nwg.x``.

Both can be lowered (never raised) with the constructor's ``limit_*``
arguments so the chunking paths can be tested on small inputs.
"""
from __future__ import annotations

import math
import struct
import threading
from collections import OrderedDict
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .adapter import select_adapter
from .shaders import check_bindings, load_shader_source

# Usage flags spelled once, so callers need not import wgpu.
STORAGE = 0x80  # wgpu.BufferUsage.STORAGE
UNIFORM = 0x40
COPY_SRC = 0x04
COPY_DST = 0x08
MAP_READ = 0x01
QUERY_RESOLVE = 0x200

_WANTED_LIMITS = (
    "max-storage-buffer-binding-size",
    "max-buffer-size",
    "max-compute-workgroup-storage-size",
    "max-compute-invocations-per-workgroup",
    "max-compute-workgroup-size-x",
    "max-compute-workgroup-size-y",
    "max-storage-buffers-per-shader-stage",
)
_OPTIONAL_FEATURES = ("subgroup", "timestamp-query", "shader-f16")
_STAGED_READ_BYTES = 256 * 1024  # reads this large use the reusable staging buffer
_UNIFORMS_KEPT = 512  # distinct uniform buffers a context keeps for reuse


#: The adapter type on which kernels with a host path take it (GpuContext.kernel_backend).
_CPU_TYPE = "CPU"


def _requested(adapter) -> tuple[dict, list]:
    """The limits and optional features a context requests of ``adapter``'s device."""
    alimits = dict(adapter.limits)
    return ({k: alimits[k] for k in _WANTED_LIMITS if k in alimits},
            [f for f in _OPTIONAL_FEATURES if f in adapter.features])


def _open_device(adapter):
    limits, features = _requested(adapter)
    return adapter.request_device_sync(label="r360gpu", required_features=features, required_limits=limits)


@dataclass(frozen=True)
class BufferRange:
    """A window of a buffer bound to one binding: ``size`` bytes from ``offset``."""

    buffer: Any
    offset: int
    size: int


@dataclass
class DeviceDepth:
    """A depth image already on the device: ``height x width`` float32,
    row-major, starting at byte ``offset`` (a multiple of 4) of ``buffer``
    (needs the STORAGE and COPY_SRC usages)."""

    buffer: Any
    height: int
    width: int
    offset: int = 0


_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")


def uniform_words(values: Sequence) -> np.ndarray:
    """32-bit scalars as the u32 words of a uniform buffer (padded with zeros to a multiple of 4
    words, at least 4): floats as float32 (rounded to nearest), ints as u32 (negative ones
    two's complement).  Packed with ``struct``, not numpy scalars: this runs for every
    recorded pass, and numpy's per-scalar conversions cost several times as much."""
    out = bytearray()
    for v in values:
        if isinstance(v, (float, np.floating)):
            try:
                out += _F32.pack(v)
            except OverflowError:  # beyond float32's range: infinity, as numpy rounds it
                out += np.float32(v).tobytes()
        else:
            i = int(v)
            out += _U32.pack(i & 0xFFFFFFFF if i < 0 else i)
    out += bytes(4 * (max(4, -(-len(values) // 4) * 4) - len(values)))
    return np.frombuffer(bytes(out), dtype=np.uint32)


class GpuContext:
    """A wgpu device with shader/pipeline caches and buffer helpers.

    Parameters
    ----------
    device:
        a ``wgpu.GPUDevice``; the caller's own device may be passed for library
        use inside another GPU pipeline (see :meth:`from_device`).
    limit_binding_bytes, limit_workgroups:
        optional lower caps on the device limits (tests use them to force the
        chunking paths on small inputs).
    """

    def __init__(self, device=None, *, limit_binding_bytes: int | None = None, limit_workgroups: int | None = None,
                 adapter=None):
        # device None: opened from ``adapter`` on first use (see :meth:`create`); until then the
        # limits and features are those it will have (tests/test_gpu_context.py compares them)
        if device is None and adapter is None:
            raise ValueError("GpuContext needs a device or an adapter to open one from")
        self._device, self._adapter = device, adapter
        self._caps = (limit_binding_bytes, limit_workgroups)
        self._open_lock = threading.Lock()
        if device is not None:
            self._set_device_facts(dict(device.limits), set(device.features), getattr(device, "adapter_info", None))
        else:
            # wgpu gives a device the adapter's limits where none is requested
            self._set_device_facts(dict(adapter.limits), set(_requested(adapter)[1]), adapter.info)
        self._modules: dict[str, Any] = {}
        self._pipelines: dict[tuple, Any] = {}
        self._checked_bindings: set[tuple] = set()  # (shader, host binding names) found to agree
        self._scratch: dict = {}
        self._staging = None
        self._uniforms: OrderedDict[bytes, Any] = OrderedDict()
        self._profile: dict | None = None
        self._lock = threading.Lock()
        self._frame = threading.local()  # .cache: the FrameCache active on this thread (recording)

    def _set_device_facts(self, limits: dict, features: set, info) -> None:
        limit_binding_bytes, limit_workgroups = self._caps
        self.limits = limits
        binding = int(limits.get("max-storage-buffer-binding-size", 128 << 20))
        buffer = int(limits.get("max-buffer-size", binding))
        binding = min(binding, buffer)
        if limit_binding_bytes is not None:
            binding = min(binding, int(limit_binding_bytes))
        # Keep bindings a multiple of 256 bytes so windows of one buffer can
        # start anywhere a binding may (offset alignment is at most 256).
        self.max_binding_bytes = max(256, binding // 256 * 256)
        wg = int(limits.get("max-compute-workgroups-per-dimension", 65535))
        self.max_workgroups = min(wg, int(limit_workgroups)) if limit_workgroups else wg
        self.storage_offset_alignment = int(limits.get("min-storage-buffer-offset-alignment", 256))
        self.features = set(features)
        info = info or {}
        self.adapter_info = {
            "name": str(info.get("device", "unknown")),
            "vendor": str(info.get("vendor", "")),
            "backend": str(info.get("backend_type", "unknown")),
            "adapter_type": str(info.get("adapter_type", "unknown")),
            "description": str(info.get("description", "")),
        }

    @property
    def device(self):
        """The ``wgpu.GPUDevice``; a context made by :meth:`create` on a CPU adapter opens it here,
        the first time anything needs it."""
        if self._device is None:
            with self._open_lock:
                if self._device is None:
                    device = _open_device(self._adapter)
                    # the device's own facts from now on (the same as requested: tests/test_gpu_context.py)
                    self._set_device_facts(dict(device.limits), set(device.features),
                                           getattr(device, "adapter_info", None))
                    self._device = device
        return self._device

    @property
    def queue(self):
        return self.device.queue

    @property
    def device_open(self) -> bool:
        """Whether the device has been opened (a deferred one opens on first use)."""
        return self._device is not None

    # -- construction -----------------------------------------------------
    @classmethod
    def create(cls, adapter: str | None = None, **kwargs) -> "GpuContext":
        """A context on the adapter chosen by ``adapter`` / ``R360GPU_ADAPTER``.

        On a CPU adapter (lavapipe) every kernel with a host path takes it (:meth:`kernel_backend`),
        so a run of those kernels never touches the device: it is opened on first use (none of
        lavapipe's device set-up where nothing renders).  On a GPU it is opened here.
        """
        ad = select_adapter(adapter)
        if str(ad.info.get("adapter_type")) == _CPU_TYPE:
            return cls(adapter=ad, **kwargs)
        return cls(_open_device(ad), **kwargs)

    @classmethod
    def from_device(cls, device, **kwargs) -> "GpuContext":
        """Wrap a caller's existing ``wgpu.GPUDevice`` (shares its queue)."""
        return cls(device, **kwargs)

    def kernel_backend(self, kernel: str) -> str:
        """"gpu" or "cpu": where a kernel with a host implementation runs on this adapter.

        On a CPU adapter (lavapipe) a compute shader is a slower way to run the
        same CPU: each submission waits on the queue, and per-invocation storage
        loads defeat vectorisation (bench/bench_measure.py measures both), so
        kernels that have an exact host path (``ssim``, ``mask_iou``,
        ``depth_change``, the renderer's ``sort``) take it there.  The environment variable ``R360GPU_<KERNEL>`` (``gpu`` or
        ``cpu``) overrides, which is how the tests run both paths on lavapipe.
        """
        import os

        forced = os.environ.get(f"R360GPU_{kernel.upper()}")
        if forced in ("gpu", "cpu"):
            return forced
        return "cpu" if self.adapter_info.get("adapter_type") == _CPU_TYPE else "gpu"

    def describe(self) -> dict:
        """Adapter name, backend and the limits that matter; goes into every result."""
        return {
            **self.adapter_info,
            "max_binding_bytes": self.max_binding_bytes,
            "max_workgroups_per_dimension": self.max_workgroups,
            "features": sorted(str(f) for f in self.features),
        }

    # -- shaders and pipelines -------------------------------------------
    def shader(self, name: str):
        """The compiled shader module of ``shaders/<name>.wgsl`` (cached)."""
        with self._lock:
            mod = self._modules.get(name)
            if mod is None:
                src = load_shader_source(name)
                mod = self.device.create_shader_module(label=name, code=src)
                self._modules[name] = mod
            return mod

    def pipeline(self, name: str, entry_point: str = "main", constants: dict | None = None,
                 bindings: Sequence[str | None] | None = None):
        """A compute pipeline for ``entry_point`` of shader ``name`` (cached).

        ``constants`` sets WGSL ``override`` declarations (e.g. workgroup size).  ``bindings``: the
        WGSL names of the resources the host binds, by position (``bindings[i]`` is the variable at
        ``@binding(i)``); a shader that declares others raises ValueError
        (`r360gpu.gpu.shaders.check_bindings`).
        """
        key = (name, entry_point, tuple(sorted((constants or {}).items())))
        with self._lock:
            pipe = self._pipelines.get(key)
        if bindings is not None and (name, tuple(bindings)) not in self._checked_bindings:
            check_bindings(name, bindings)
            with self._lock:
                self._checked_bindings.add((name, tuple(bindings)))
        if pipe is None:
            stage = {"module": self.shader(name), "entry_point": entry_point}
            if constants:
                stage["constants"] = {k: float(v) for k, v in constants.items()}
            pipe = self.device.create_compute_pipeline(
                label=f"{name}:{entry_point}", layout="auto", compute=stage
            )
            with self._lock:
                self._pipelines[key] = pipe
        return pipe

    # -- buffers ----------------------------------------------------------
    def buffer(self, data: np.ndarray | bytes | int, *, usage: int = STORAGE | COPY_SRC | COPY_DST, label: str = ""):
        """A buffer holding ``data`` (array/bytes) or ``data`` zero bytes (int).

        Sizes are rounded up to a multiple of 4 bytes (and at least 4), as wgpu
        requires for copies.
        """
        if isinstance(data, (int, np.integer)):
            size = max(4, int(math.ceil(int(data) / 4) * 4))
            return self.device.create_buffer(label=label, size=size, usage=usage)
        if isinstance(data, np.ndarray) and data.nbytes and data.nbytes % 4 == 0:
            # No intermediate copy: wgpu reads the array's memory directly.
            return self.device.create_buffer_with_data(label=label, data=np.ascontiguousarray(data), usage=usage)
        raw = np.ascontiguousarray(data).tobytes() if isinstance(data, np.ndarray) else bytes(data)
        raw = raw + b"\0" * (-len(raw) % 4 if raw else 4)
        return self.device.create_buffer_with_data(label=label, data=raw, usage=usage)

    def scratch(self, key, data: np.ndarray):
        """A reusable buffer for ``key`` holding ``data`` (written with a queue copy).

        For per-call uploads of the same size (e.g. the depth images of every
        view): reusing one buffer avoids allocating and first-touching fresh
        memory each call.  The caller must be done with the previous contents
        (i.e. the passes reading it were submitted before this call).
        """
        data = np.ascontiguousarray(data)
        nbytes = max(4, int(math.ceil(data.nbytes / 4) * 4))
        buf = self.reusable(key, nbytes, exact=True)
        if data.nbytes % 4:
            data = np.concatenate([data.view(np.uint8).reshape(-1), np.zeros(-data.nbytes % 4, np.uint8)])
        self.queue.write_buffer(buf, 0, data)
        return buf

    def reusable(self, key, nbytes: int, exact: bool = False):
        """A storage buffer kept for ``key`` across calls: at least ``nbytes`` bytes (``exact``:
        exactly), reallocated only when that does not hold; contents undefined."""
        nbytes = max(4, int(math.ceil(int(nbytes) / 4) * 4))
        with self._lock:
            buf = self._scratch.get(key)
            if buf is None or (buf.size != nbytes if exact else buf.size < nbytes):
                buf = self.device.create_buffer(label=str(key), size=nbytes, usage=STORAGE | COPY_SRC | COPY_DST)
                self._scratch[key] = buf
        return buf

    def uniform(self, *values, label: str = "params"):
        """A uniform buffer from 32-bit scalars: ints become u32/i32, floats f32.

        The WGSL struct must list the fields in the same order, all 32-bit.
        Nothing writes a uniform buffer after this, so equal contents share
        one buffer (the last ``_UNIFORMS_KEPT`` distinct ones are kept): the
        renderer's dispatches of one view repeat in the next, and creating a
        buffer was most of the host's cost of recording a dispatch.  Under
        `recording` the frame cache's buffers serve instead.
        """
        words = uniform_words(values)
        frame = getattr(self._frame, "cache", None)
        if frame is not None:
            return frame.uniform(words, lambda: self.buffer(words, usage=UNIFORM | COPY_DST, label=label), self.write)
        key = words.tobytes()
        with self._lock:
            buf = self._uniforms.get(key)
            if buf is not None:
                self._uniforms.move_to_end(key)
                return buf
        buf = self.buffer(words, usage=UNIFORM | COPY_DST, label=label)
        with self._lock:
            self._uniforms[key] = buf
            while len(self._uniforms) > _UNIFORMS_KEPT:
                self._uniforms.popitem(last=False)
        return buf

    def write(self, buffer, data: np.ndarray, offset: int = 0) -> None:
        self.queue.write_buffer(buffer, offset, np.ascontiguousarray(data))

    def read(self, buffer, dtype=np.uint8, count: int | None = None, offset: int = 0) -> np.ndarray:
        """Copy ``count`` elements of ``dtype`` from ``buffer`` (at byte ``offset``) to the host.

        Large reads go through one reusable mappable staging buffer (a fresh
        staging buffer per read costs more than the copy itself: 52 MB read
        in 12 ms instead of 80-180 ms on lavapipe).
        """
        itemsize = np.dtype(dtype).itemsize
        size = buffer.size - offset if count is None else count * itemsize
        if size <= 0:
            return np.zeros(0, dtype=dtype)
        padded = int(math.ceil(size / 4) * 4)
        if padded < _STAGED_READ_BYTES:
            raw = self.queue.read_buffer(buffer, offset, padded)
            return np.frombuffer(raw, dtype=np.uint8)[:size].view(dtype).copy()
        with self._lock:
            staging = self._staging
            if staging is None or staging.size < padded:
                if staging is not None:
                    staging.destroy()
                staging = self._staging = self.device.create_buffer(
                    label="r360gpu-staging", size=padded, usage=MAP_READ | COPY_DST)
            enc = self.device.create_command_encoder()
            enc.copy_buffer_to_buffer(buffer, offset, staging, 0, padded)
            self.queue.submit([enc.finish()])
            staging.map_sync(MAP_READ, 0, padded)
            try:
                out = np.frombuffer(staging.read_mapped(0, padded, copy=False), dtype=np.uint8)[:size].view(dtype).copy()
            finally:
                staging.unmap()
        return out

    # -- dispatch ---------------------------------------------------------
    def grid(self, groups: int) -> tuple[int, int, int]:
        """Fold a 1-D workgroup count into (x, y, 1) within the per-dimension limit."""
        groups = max(0, int(groups))
        if groups <= self.max_workgroups:
            return (groups, 1, 1)
        y = int(math.ceil(groups / self.max_workgroups))
        if y > self.max_workgroups:
            raise ValueError(f"{groups} workgroups exceed one 2-D dispatch; chunk the input")
        return (int(math.ceil(groups / y)), y, 1)

    def bind_group(self, pipeline, resources: Sequence, group: int = 0):
        """A bind group for ``pipeline``: ``resources[i]`` goes to ``@binding(i)``.

        Each resource is a buffer (bound whole), a :class:`BufferRange`, or
        ``None`` for a binding the entry point does not use.  Under
        `recording` an equal bind group of the frame before is reused.
        """
        frame = getattr(self._frame, "cache", None)
        if frame is not None:
            key = (pipeline, group, tuple(r if r is None or isinstance(r, BufferRange) else BufferRange(r, 0, r.size)
                                          for r in resources))
            return frame.bind_group(key, lambda: self._create_bind_group(pipeline, resources, group))
        return self._create_bind_group(pipeline, resources, group)

    def _create_bind_group(self, pipeline, resources: Sequence, group: int):
        entries = []
        for i, res in enumerate(resources):
            if res is None:
                continue
            if isinstance(res, BufferRange):
                entries.append({"binding": i, "resource": {"buffer": res.buffer, "offset": res.offset, "size": res.size}})
            else:
                entries.append({"binding": i, "resource": {"buffer": res, "offset": 0, "size": res.size}})
        return self.device.create_bind_group(layout=pipeline.get_bind_group_layout(group), entries=entries)

    def span(self, buffer, offset: int, nbytes: int) -> BufferRange:
        """A binding of ``buffer`` from ``offset`` holding at least ``nbytes``: the rest of the
        buffer, up to one storage binding.

        For data whose length changes from frame to frame in a buffer that does not (the
        renderer's key lists): the binding, and so a kept bind group (`recording`),
        stays the same.  Only for kernels that bound their loops by a count they are
        given, never by the binding's length (``arrayLength``).
        """
        rest = min(buffer.size - offset, self.max_binding_bytes) // 4 * 4
        return BufferRange(buffer, offset, max(int(nbytes), rest))

    @contextmanager
    def recording(self, cache):
        """Record with ``cache`` (a `FrameCache` of `r360gpu.gpu.recording`) on this thread:
        `uniform` and `bind_group` reuse what the frame before created."""
        before = getattr(self._frame, "cache", None)
        self._frame.cache = cache
        try:
            yield cache
        finally:
            self._frame.cache = before

    def encoder(self):
        return self.device.create_command_encoder()

    def dispatch(self, encoder, pipeline, resources: Sequence, groups: Sequence[int] | int) -> None:
        """Record one compute pass on ``encoder``."""
        if isinstance(groups, (int, np.integer)):
            groups = self.grid(int(groups))
        groups = tuple(int(g) for g in groups) + (1,) * (3 - len(groups))
        if min(groups) == 0:
            return
        if max(groups) > self.max_workgroups:
            raise ValueError(f"dispatch {groups} exceeds {self.max_workgroups} workgroups per dimension")
        bg = self.bind_group(pipeline, resources)
        prof = self._profile
        if prof is not None and len(prof["labels"]) < prof["capacity"]:
            i = len(prof["labels"])
            prof["labels"].append(getattr(pipeline, "label", "") or "unlabelled")
            cp = encoder.begin_compute_pass(timestamp_writes={
                "query_set": prof["set"], "beginning_of_pass_write_index": 2 * i, "end_of_pass_write_index": 2 * i + 1})
        else:
            cp = encoder.begin_compute_pass()
        cp.set_pipeline(pipeline)
        cp.set_bind_group(0, bg)
        cp.dispatch_workgroups(*groups)
        cp.end()

    # -- device time per kernel (benchmarks) ---------------------------
    def profile_begin(self, capacity: int = 2048) -> bool:
        """Time every compute pass :meth:`dispatch` records from now on the device (timestamp
        queries; the first ``capacity`` passes: wgpu allows 4096 queries, two per pass, per set).
        False (and nothing timed) when the device lacks the ``timestamp-query`` feature."""
        if "timestamp-query" not in self.features:
            return False
        qs = self.device.create_query_set(type="timestamp", count=2 * capacity)
        self._profile = {"set": qs, "labels": [], "capacity": capacity}
        return True

    def profile_end(self) -> dict[str, tuple[int, float]]:
        """Stop timing; {pipeline label: (passes, device seconds)} since :meth:`profile_begin`.

        Waits for the device.  Seconds are the timestamps' difference read as nanoseconds
        (WebGPU's unit; wgpu passes the Vulkan ticks on, which are nanoseconds where the
        driver's timestamp period is 1, as on NVIDIA and lavapipe).
        """
        prof, self._profile = self._profile, None
        if not prof:
            return {}
        out: dict[str, tuple[int, float]] = {}
        n = 2 * len(prof["labels"])
        if n:
            buf = self.device.create_buffer(label="r360gpu-timestamps", size=n * 8, usage=QUERY_RESOLVE | COPY_SRC)
            enc = self.encoder()
            enc.resolve_query_set(prof["set"], 0, n, buf, 0)
            self.submit(enc)
            ticks = self.read(buf, np.uint64, n).reshape(-1, 2).astype(np.int64)
            buf.destroy()
            for label, (a, b) in zip(prof["labels"], ticks):
                count, secs = out.get(label, (0, 0.0))
                out[label] = (count + 1, secs + max(0, int(b - a)) * 1e-9)
        prof["set"].destroy()
        return out

    def submit(self, encoder) -> None:
        self.queue.submit([encoder.finish()])

    def run(self, pipeline, resources: Sequence, groups) -> None:
        """Record and submit a single pass."""
        enc = self.encoder()
        self.dispatch(enc, pipeline, resources, groups)
        self.submit(enc)


_contexts: dict[str, GpuContext] = {}
_contexts_lock = threading.Lock()


def get_context(adapter: str | None = None, device=None) -> GpuContext:
    """The shared context for ``adapter`` (see `r360gpu.gpu.adapter`), or
    a context around the caller's ``device``.  Contexts are created once per
    adapter choice and reused."""
    if device is not None:
        if isinstance(device, GpuContext):
            return device
        with _contexts_lock:
            key = f"device:{id(device)}"
            ctx = _contexts.get(key)
            if ctx is None or ctx.device is not device:
                ctx = _contexts[key] = GpuContext.from_device(device)
            return ctx
    import os

    from .adapter import ENV_VAR

    key = (adapter or os.environ.get(ENV_VAR) or "auto").strip().lower()
    with _contexts_lock:
        ctx = _contexts.get(key)
        if ctx is None:
            ctx = _contexts[key] = GpuContext.create(adapter)
        return ctx


def open_ahead(adapter: str | None = None) -> None:
    """Start :func:`get_context` for ``adapter`` on a thread of its own, so that importing wgpu and
    choosing the adapter (much of it in the driver with the GIL released) overlap
    the caller's other start-up work.  A failure is left for the caller's own ``get_context`` call,
    which tries again and raises it there."""
    def run() -> None:
        try:
            get_context(adapter)
        except Exception:  # noqa: BLE001 - raised again where the run asks for its context
            pass

    threading.Thread(target=run, name="r360-gpu-ahead", daemon=True).start()
