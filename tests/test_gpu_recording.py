"""Frame caches (GpuContext.recording), uniform packing and whole-buffer bindings (GpuContext.span)."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.gpu import BufferRange, GpuContext
from r360gpu.gpu.context import uniform_words
from r360gpu.gpu.recording import FrameCache
from r360gpu.render.scratch import Scratch
from r360gpu.render.sort import radix_sort


def numpy_words(values) -> np.ndarray:
    """The packing by numpy scalars that uniform_words replaced."""
    words = np.zeros(max(4, -(-len(values) // 4) * 4), dtype=np.uint32)
    for i, v in enumerate(values):
        if isinstance(v, (float, np.floating)):
            with np.errstate(over="ignore"):
                words[i] = np.float32(v).view(np.uint32)
        else:
            words[i] = np.int64(v).astype(np.uint32) if int(v) < 0 else np.uint32(int(v))
    return words


def test_uniform_words_match_numpy():
    """Rounding to nearest, subnormals, -0, NaN, infinities, float32 overflow, u32 and negative ints."""
    rng = np.random.default_rng(0)
    values = [0.1, -0.0, 1e-40, 3.4028235e38, 3.5e38, -1e39, float("inf"), float("-inf"), float("nan"),
              np.float32(2.5), np.float64(1 / 3), 0, 1, 2**32 - 1, -1, -(2**31), True, False, np.uint32(7),
              np.int64(-5), *rng.normal(0, 1e3, 20).tolist(), *rng.integers(0, 2**32, 5).tolist()]
    for n in range(len(values) + 1):
        with np.errstate(over="ignore"):  # 3.5e38 and -1e39 round to infinities, with numpy's warning
            got = uniform_words(values[:n])
        np.testing.assert_array_equal(got, numpy_words(values[:n]), err_msg=str(n))


def test_frame_cache_reuses_and_rewrites(ctx):
    """Per frame, the i-th uniform is the cache's i-th buffer, rewritten when its contents change;
    a bind group over the same ranges is reused; what a frame did not use is dropped."""
    c = GpuContext(ctx.device)
    cache = FrameCache()
    pipe = c.pipeline("render_ranges")
    data, out = c.buffer(1024), c.buffer(256)
    with c.recording(cache):
        cache.begin_frame()
        u0, u1 = c.uniform(1, 2.0), c.uniform(3)
        g = c.bind_group(pipe, [u0, BufferRange(data, 0, 512), out])
        cache.begin_frame()
        assert c.uniform(1, 2.0) is u0 and c.uniform(4) is u1
        assert c.bind_group(pipe, [u0, BufferRange(data, 0, 512), out]) is g
        assert c.bind_group(pipe, [u0, BufferRange(data, 0, 256), out]) is not g
        cache.begin_frame()
        cache.begin_frame()  # a frame that used nothing: everything dropped
        assert c.bind_group(pipe, [u0, BufferRange(data, 0, 512), out]) is not g
    assert cache.counts == dict(groups_created=3, groups_reused=1, uniforms_created=2, uniforms_written=1)
    assert c.uniform(1, 2.0) is not u0  # outside recording: the context's shared uniforms
    cache.clear()


@pytest.mark.parametrize("variant,limit", [("blocks", None), ("serial", 4096)])
def test_sorts_of_changing_lengths_in_one_cache(ctx, variant, limit):
    """Frames sorting different counts in the same scratch buffers, uniforms rewritten in place
    between them, in one binding or (4 KiB bindings) in windows: each sort is right; a frame sorting
    as many as the one before creates no bind group, nor (in one binding) one sorting fewer."""
    c = GpuContext(ctx.device, limit_binding_bytes=limit)
    cache, scratch = FrameCache(), Scratch(c)
    rng = np.random.default_rng(1)
    kb, vb = scratch.get("k", 5000 * 4), scratch.get("v", 5000 * 4)
    created = []
    for n in (5000, 3100, 4999, 4999):
        keys = rng.integers(0, 2**13, n, dtype=np.uint64).astype(np.uint32)
        c.write(kb, keys)
        c.write(vb, np.arange(n, dtype=np.uint32))
        cache.begin_frame()
        with c.recording(cache):
            enc = c.encoder()
            ks, vs = radix_sort(c, enc, kb, vb, n, 13, scratch, "t", variant=variant)
            c.submit(enc)
        np.testing.assert_array_equal(c.read(vs, np.uint32, n), np.argsort(keys, kind="stable"))
        created.append(cache.counts["groups_created"])
    assert created[3] == created[2] > 0
    if limit is None:
        assert created[0] == created[1] == created[2]
    cache.clear()
    scratch.release()


def test_span_binds_the_rest_of_the_buffer(ctx):
    small = GpuContext(ctx.device, limit_binding_bytes=4096)
    buf = small.buffer(10_000)
    assert small.span(buf, 0, 40) == BufferRange(buf, 0, 4096)
    assert small.span(buf, 8192, 4) == BufferRange(buf, 8192, 10_000 - 8192)
