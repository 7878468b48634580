"""The portable radix sort (both shader variants) and prefix sum against numpy."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.gpu import GpuContext
from r360gpu.render.scan import exclusive_scan
from r360gpu.render.scratch import Scratch
from r360gpu.render.sort import (BLOCK, VARIANT_ENV, VARIANTS, host_argsort, host_sort, sort_pairs, sort_variant,
                                  window_elements)

BLOCKS_BLOCK = 1024  # radix_sort_blocks.wgsl's BLOCK (test_variant_block_sizes checks it)


@pytest.fixture(params=sorted(VARIANTS))
def variant(request):
    """Every sort test runs both shader variants (lavapipe runs the GPU one too)."""
    return request.param


def _check(ctx, keys, bits=32, variant=None):
    keys = np.asarray(keys, dtype=np.uint32)
    vals = np.arange(keys.size, dtype=np.uint32)[::-1].copy()  # values differ from positions
    ks, vs = sort_pairs(ctx, keys, vals, bits=bits, variant=variant)
    masked = keys & np.uint32((1 << bits) - 1) if bits < 32 else keys
    order = np.argsort(masked, kind="stable")
    np.testing.assert_array_equal(vs, vals[order])
    np.testing.assert_array_equal(ks, keys[order])
    # the renderer's host path (CPU adapters) applies the same permutation
    np.testing.assert_array_equal(vals[host_argsort(keys, bits)], vs)


@pytest.mark.parametrize("n", sorted({0, 1, 2, 255, 256, 257, BLOCK - 1, BLOCK, BLOCK + 1, 3 * BLOCK + 77,
                                       BLOCKS_BLOCK - 1, BLOCKS_BLOCK + 1, 5 * BLOCKS_BLOCK + 3}))
def test_random_keys(ctx, n, variant):
    rng = np.random.default_rng(n)
    _check(ctx, rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32), variant=variant)


def test_duplicates_and_all_equal(ctx, variant):
    rng = np.random.default_rng(1)
    _check(ctx, rng.integers(0, 7, 9000).astype(np.uint32), variant=variant)
    _check(ctx, np.full(5000, 123456789, np.uint32), variant=variant)
    # all-ones keys: the blocks variant pads a block's tail with the all-ones digit
    _check(ctx, np.full(3000, 0xFFFFFFFF, np.uint32), variant=variant)
    _check(ctx, np.full(1, 0xFFFFFFFF, np.uint32), variant=variant)
    keys = rng.integers(0, 2**32, 2500, dtype=np.uint64).astype(np.uint32)
    keys[rng.random(2500) < 0.5] = 0xFFFFFFFF
    _check(ctx, keys, variant=variant)
    _check(ctx, keys, bits=12, variant=variant)  # 8 + 4 bits: a narrower last digit


def test_partial_bits_and_float_keys(ctx, variant):
    rng = np.random.default_rng(2)
    # Keys above the sorted bits: only the low 13 bits order, the rest rides along.
    _check(ctx, rng.integers(0, 2**13, 7000).astype(np.uint32), bits=13, variant=variant)
    # Positive float32 bit patterns sort like the floats (the depth keys).
    z = rng.lognormal(0.0, 2.0, 6000).astype(np.float32)
    z[::5] = z[0]
    ks, vs = sort_pairs(ctx, z.view(np.uint32), variant=variant)
    np.testing.assert_array_equal(vs, np.argsort(z, kind="stable"))


def test_sorted_and_reversed(ctx, variant):
    _check(ctx, np.arange(5000, dtype=np.uint32), variant=variant)
    _check(ctx, np.arange(5000, dtype=np.uint32)[::-1].copy(), variant=variant)
    # one digit value per block run, descending: every scatter writes whole runs
    _check(ctx, np.repeat(np.arange(255, -1, -1, dtype=np.uint32) << 8, 37), variant=variant)


@pytest.mark.parametrize("variant,limit,n", [
    ("serial", 4096, 1024), ("serial", 4096, 1025), ("serial", 4096, 4096 + 3), ("serial", 4096, 20000),
    # the blocks variant's histogram (256 buckets per 1,024-element block) must fit the binding too;
    # 36,608 bytes = 9,152 elements: windows that end inside a block
    ("blocks", 36608, 9152), ("blocks", 36608, 9153), ("blocks", 36608, 20000), ("blocks", 36608, 30001),
])
def test_over_one_binding(ctx, variant, limit, n):
    """Inputs larger than a (lowered) storage binding are sorted in windows."""
    small = GpuContext(ctx.device, limit_binding_bytes=limit, limit_workgroups=7)
    assert n * 4 > small.max_binding_bytes or n * 4 == small.max_binding_bytes
    assert window_elements(small, variant) * 4 == small.max_binding_bytes
    rng = np.random.default_rng(n)
    keys = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    keys[::3] = keys[1]
    _check(small, keys, variant=variant)
    _check(small, keys, bits=16, variant=variant)


def test_variant_choice(ctx, monkeypatch):
    """Serial (CPU-tuned) on CPU adapters, blocks on GPUs; R360GPU_RADIX_VARIANT overrides."""
    from r360gpu.gpu.shaders import shader_constants

    assert shader_constants("radix_sort_blocks")["BLOCK"] == BLOCKS_BLOCK
    monkeypatch.delenv(VARIANT_ENV, raising=False)
    expect = "serial" if ctx.adapter_info["adapter_type"] == "CPU" else "blocks"
    assert sort_variant(ctx) == expect
    fake = GpuContext(ctx.device)
    fake.adapter_info = {**ctx.adapter_info, "adapter_type": "DiscreteGPU"}
    assert sort_variant(fake) == "blocks"
    fake.adapter_info["adapter_type"] = "CPU"
    assert sort_variant(fake) == "serial"
    monkeypatch.setenv(VARIANT_ENV, "blocks")
    assert sort_variant(fake) == "blocks"
    monkeypatch.setenv(VARIANT_ENV, "fast")
    with pytest.raises(ValueError, match=VARIANT_ENV):
        sort_variant(fake)


@pytest.mark.parametrize("n", [0, 1, 2047, 2048, 2049, 3 * 2048 * 2 + 5])
def test_exclusive_scan(ctx, n):
    rng = np.random.default_rng(n)
    data = rng.integers(0, 1000, n).astype(np.uint32)
    buf = ctx.buffer(data if n else 4)
    scratch = Scratch(ctx)
    enc = ctx.encoder()
    total = exclusive_scan(ctx, enc, buf, n, scratch)
    ctx.submit(enc)
    got = ctx.read(buf, np.uint32, n)
    expect = np.concatenate([[0], np.cumsum(data)[:-1]]).astype(np.uint32) if n else data
    np.testing.assert_array_equal(got, expect)
    assert int(ctx.read(total.buffer, np.uint32, 1, total.offset)[0]) == int(data.sum())


@pytest.mark.slow
def test_exclusive_scan_three_levels(ctx):
    n = BLOCK * BLOCK + 5
    data = np.random.default_rng(0).integers(0, 3, n).astype(np.uint32)
    buf = ctx.buffer(data)
    enc = ctx.encoder()
    total = exclusive_scan(ctx, enc, buf, n, Scratch(ctx))
    ctx.submit(enc)
    got = ctx.read(buf, np.uint32, n)
    np.testing.assert_array_equal(got[1:], np.cumsum(data)[:-1].astype(np.uint32))
    assert int(ctx.read(total.buffer, np.uint32, 1, total.offset)[0]) == int(data.sum())


@pytest.mark.parametrize("bits", [0, 1, 3, 4, 5, 10, 12, 16, 17, 20, 31, 32])
def test_host_argsort_is_the_radix_permutation(ctx, bits, variant):
    """host_argsort = sort_pairs's permutation for every bit count, keys with bits above the
    sorted ones (radix passes sort 4 * ceil(bits / 4) bits), ties, and the 16-bit halves' edges."""
    rng = np.random.default_rng(bits)
    keys = rng.integers(0, 2**32, 6000, dtype=np.uint64).astype(np.uint32)
    keys[::4] = rng.choice(np.array([0, 0xFFFF, 0x10000, 0xFFFF0000, 0xFFFFFFFF], np.uint32), keys[::4].size)
    keys[1::7] = keys[2]
    _, vs = sort_pairs(ctx, keys, bits=bits, variant=variant)
    np.testing.assert_array_equal(host_argsort(keys, bits), vs)


def test_host_argsort_small():
    assert host_argsort(np.zeros(0, np.uint32), 32).size == 0
    np.testing.assert_array_equal(host_argsort(np.array([5], np.uint32), 32), [0])
    np.testing.assert_array_equal(host_argsort(np.array([3, 1, 2, 1], np.uint32), 0), [0, 1, 2, 3])


@pytest.mark.parametrize("bits", [0, 10, 32])
def test_host_sort_sorts_device_buffers_in_place(ctx, bits):
    rng = np.random.default_rng(5 + bits)
    keys = rng.integers(0, 2**32, 3000, dtype=np.uint64).astype(np.uint32)
    keys[::5] = keys[3]
    vals = rng.integers(0, 2**32, 3000, dtype=np.uint64).astype(np.uint32)
    want_k, want_v = sort_pairs(ctx, keys, vals, bits=bits)
    kb, vb = ctx.buffer(np.concatenate([keys, [7, 7]]).astype(np.uint32)), ctx.buffer(vals)
    ks, vs = host_sort(ctx, kb, vb, 3000, bits)
    assert ks is kb and vs is vb
    np.testing.assert_array_equal(ctx.read(kb, np.uint32, 3002), np.concatenate([want_k, [7, 7]]))  # tail untouched
    np.testing.assert_array_equal(ctx.read(vb, np.uint32, 3000), want_v)
