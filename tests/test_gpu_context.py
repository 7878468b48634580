"""Adapter choice, the missing-driver error, caller devices, buffers and limits."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import GpuUnavailableError
from r360gpu.gpu import GpuContext, adapter as adapter_mod, get_context
from r360gpu.kernels import mask_iou
from r360gpu.kernels.reference import mask_iou_reference


def test_cpu_adapter_is_found_by_name_and_kind():
    a = adapter_mod.select_adapter("cpu")
    assert a.info["adapter_type"] == "CPU" or "llvmpipe" in a.info["device"].lower()
    assert adapter_mod.select_adapter("llvmpipe").info["device"] == a.info["device"]


def test_environment_variable_chooses(monkeypatch):
    monkeypatch.setenv(adapter_mod.ENV_VAR, "no-such-gpu-xyz")
    with pytest.raises(GpuUnavailableError, match="no adapter matches .*no-such-gpu-xyz.*available: "):
        adapter_mod.select_adapter()


def test_no_adapter_says_how_to_install_the_driver(monkeypatch):
    monkeypatch.setattr(adapter_mod, "list_adapters", lambda: [])
    with pytest.raises(GpuUnavailableError, match="apt-get install -y mesa-vulkan-drivers"):
        adapter_mod.select_adapter("auto")


def test_auto_prefers_a_native_gpu(monkeypatch):
    class Fake:
        def __init__(self, kind, backend, name):
            self.info = {"adapter_type": kind, "backend_type": backend, "device": name}

    fakes = [Fake("CPU", "Vulkan", "llvmpipe"), Fake("DiscreteGPU", "OpenGL", "gl-gpu"), Fake("DiscreteGPU", "Vulkan", "vk-gpu")]
    monkeypatch.setattr(adapter_mod, "list_adapters", lambda: fakes)
    assert adapter_mod.select_adapter("auto").info["device"] == "vk-gpu"
    assert adapter_mod.select_adapter("cpu").info["device"] == "llvmpipe"
    monkeypatch.setattr(adapter_mod, "list_adapters", lambda: fakes[:2])
    # a native CPU adapter beats a GPU that only has OpenGL
    assert adapter_mod.select_adapter("auto").info["device"] == "llvmpipe"


def test_context_describes_adapter(ctx):
    d = ctx.describe()
    assert d["name"] and d["backend"] in ("Vulkan", "Metal", "D3D12", "OpenGL")
    assert d["max_binding_bytes"] >= 1 << 20 and d["max_workgroups_per_dimension"] >= 1


def test_callers_device_is_used(ctx):
    """Library use: wrap a device another pipeline already owns."""
    mine = get_context(device=ctx.device)
    assert mine.device is ctx.device and get_context(device=ctx.device) is mine
    a = np.eye(8, dtype=bool)[None]
    assert mask_iou.mask_iou(a, a, ctx=mine).iou[0, 0] == 1.0


def test_buffers_round_trip(ctx):
    x = np.arange(10, dtype=np.float32)
    buf = ctx.buffer(x)
    np.testing.assert_array_equal(ctx.read(buf, np.float32, 10), x)
    odd = ctx.buffer(np.arange(5, dtype=np.uint8))  # padded to 8 bytes
    np.testing.assert_array_equal(ctx.read(odd, np.uint8, 5), np.arange(5))
    assert ctx.buffer(b"").size >= 4
    ctx.write(buf, np.full(2, 7, np.float32), offset=8)
    assert ctx.read(buf, np.float32, 4)[2] == 7


def test_grid_folds_large_dispatches(ctx):
    small = GpuContext(ctx.device, limit_workgroups=10)
    assert small.grid(7) == (7, 1, 1)
    x, y, z = small.grid(95)
    assert x <= 10 and y <= 10 and x * y >= 95
    with pytest.raises(ValueError, match="chunk"):
        small.grid(101)


def test_limits_can_only_be_lowered(ctx):
    c = GpuContext(ctx.device, limit_binding_bytes=10**15)
    assert c.max_binding_bytes == ctx.max_binding_bytes
    assert GpuContext(ctx.device, limit_binding_bytes=1000).max_binding_bytes == 768


def test_atomic_writes_respect_the_umask(tmp_path):
    import os

    from r360gpu.util.atomic import write_text

    old = os.umask(0o022)
    try:
        write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o644
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp file left


def test_large_reads_use_the_staging_buffer(ctx):
    from r360gpu.gpu import context as C

    x = np.random.default_rng(3).random(C._STAGED_READ_BYTES // 4 * 3 + 7).astype(np.float32)
    buf = ctx.buffer(x)
    np.testing.assert_array_equal(ctx.read(buf, np.float32), x)
    np.testing.assert_array_equal(ctx.read(buf, np.float32, 1000, offset=400), x[100:1100])  # small: direct
    np.testing.assert_array_equal(ctx.read(buf, np.float32, x.size - 10, offset=40), x[10:])  # large, offset
    small_then_large = ctx.buffer(np.arange(10, dtype=np.uint8))
    np.testing.assert_array_equal(ctx.read(small_then_large, np.uint8, 10), np.arange(10))


def test_equal_uniforms_share_one_buffer(ctx, monkeypatch):
    """Uniform buffers are never written after creation, so equal contents are one buffer;
    the kept set is bounded, and a shared buffer still feeds its kernel the right values."""
    from r360gpu.gpu import context as C
    from r360gpu.render.sort import sort_pairs

    fresh = GpuContext(ctx.device)
    a = fresh.uniform(3, 1.5, -2)
    assert fresh.uniform(3, 1.5, -2) is a
    assert fresh.uniform(3, 1.5, -1) is not a and fresh.uniform(3, 2.5, -2) is not a
    monkeypatch.setattr(C, "_UNIFORMS_KEPT", 4)
    for i in range(6):
        fresh.uniform(100 + i)
    assert len(fresh._uniforms) == 4 and fresh.uniform(3, 1.5, -2) is not a
    # two sorts recording the same uniforms give the same (right) result
    keys = np.random.default_rng(4).integers(0, 2**32, 3000, dtype=np.uint64).astype(np.uint32)
    for _ in range(2):
        _, order = sort_pairs(fresh, keys)
        np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))


def test_device_time_per_kernel(ctx):
    """profile_begin/end: one entry per pipeline label with its pass count (what bench_render.py
    --gpu-times prints); nothing without the timestamp-query feature or after the end."""
    from r360gpu.render.sort import sort_pairs

    fresh = GpuContext(ctx.device)
    assert fresh.profile_end() == {}
    keys = np.random.default_rng(6).integers(0, 2**32, 5000, dtype=np.uint64).astype(np.uint32)
    if "timestamp-query" in fresh.features:
        assert fresh.profile_begin()
        sort_pairs(fresh, keys, bits=16, variant="blocks")
        times = fresh.profile_end()
        assert times["radix_sort_blocks:histogram"][0] == 2 and times["radix_sort_blocks:scatter"][0] == 2
        assert all(secs >= 0 for _, secs in times.values())
        sort_pairs(fresh, keys, bits=16, variant="blocks")  # after the end: untimed
        assert fresh.profile_end() == {}
    fresh.features = fresh.features - {"timestamp-query"}
    assert not fresh.profile_begin() and fresh.profile_end() == {}


def _facts(c: GpuContext) -> dict:
    return {**c.describe(), "limits": {k: c.limits.get(k) for k in (
        "max-storage-buffer-binding-size", "max-buffer-size", "max-compute-workgroups-per-dimension",
        "min-storage-buffer-offset-alignment")}, "alignment": c.storage_offset_alignment}


def test_cpu_adapter_context_opens_its_device_on_first_use():
    """On a CPU adapter the device waits for its first use; what the context says of it before
    (results.json's adapter entry, the limits kernels split by) is what the opened device says."""
    c = GpuContext.create("cpu")
    assert c.adapter_info["adapter_type"] == "CPU" and not c.device_open
    before = _facts(c)
    rng = np.random.default_rng(0)
    a, b = rng.uniform(size=(3, 17, 9)) < 0.5, rng.uniform(size=(2, 17, 9)) < 0.5
    assert c.kernel_backend("mask_iou") == "cpu"
    np.testing.assert_array_equal(mask_iou.mask_iou(a, b, ctx=c).iou, mask_iou_reference(a, b)[3])
    assert not c.device_open  # the host path never touched it
    buf = c.buffer(np.arange(5, dtype=np.uint32))  # first use opens it
    assert c.device_open
    np.testing.assert_array_equal(c.read(buf, np.uint32), np.arange(5, dtype=np.uint32))
    assert _facts(c) == before
    with pytest.raises(ValueError, match="needs a device or an adapter"):
        GpuContext()
