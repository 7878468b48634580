"""Batched mask IoU kernel against its numpy oracle."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from r360gpu.errors import InputError
from r360gpu.kernels import mask_iou as K

from oracles import mask_iou_oracle


@pytest.fixture(autouse=True, params=["gpu", "cpu"])
def backend(request, monkeypatch):
    """Every test runs the WGSL kernel and the host path (which CPU adapters take by default)."""
    monkeypatch.setenv("R360GPU_MASK_IOU", request.param)
    return request.param


def test_backend_default_follows_the_adapter(ctx, monkeypatch):
    monkeypatch.delenv("R360GPU_MASK_IOU")
    assert ctx.kernel_backend("mask_iou") == ("cpu" if ctx.adapter_info["adapter_type"] == "CPU" else "gpu")


def test_host_path_uploads_nothing_until_a_kernel_needs_it(ctx, backend):
    rng = np.random.default_rng(5)
    a, b = rng.random((3, 9, 40)) < 0.4, rng.random((2, 9, 40)) < 0.4
    pa = K.pack(a, ctx=ctx)
    assert (not pa.chunks) == (backend == "cpu")
    np.testing.assert_array_equal(K.mask_iou(pa, b, ctx=ctx).intersection, mask_iou_oracle(a, b)[0])
    assert (not pa.chunks) == (backend == "cpu")
    np.testing.assert_array_equal(K.union(pa, ctx=ctx), a.any(axis=0))
    np.testing.assert_array_equal(K.to_host(pa, ctx=ctx), K.pack_bits(a))
    # a GPU consumer still gets device chunks from a host-packed stack
    assert K.device_chunks(pa, ctx) and K.to_host(pa, ctx=ctx).shape == (3, 9, 2)


def _check(a, b, ctx):
    r = K.mask_iou(a, b, ctx=ctx)
    inter, aa, ab, iou = mask_iou_oracle(a, b)
    np.testing.assert_array_equal(r.intersection, inter)
    np.testing.assert_array_equal(r.area_a, aa)
    np.testing.assert_array_equal(r.area_b, ab)
    np.testing.assert_allclose(r.iou, iou, rtol=0, atol=1e-12)
    return r


@pytest.mark.parametrize("shape", [(1, 1), (1, 31), (1, 33), (5, 7), (48, 64), (45, 67), (17, 95), (64, 32)])
def test_random_masks_match_oracle(ctx, shape):
    rng = np.random.default_rng(hash(shape) % 2**32)
    a = rng.random((4, *shape)) < 0.3
    b = rng.random((6, *shape)) < 0.5
    _check(a, b, ctx)


def test_adversarial_masks(ctx):
    h, w = 37, 70  # odd width, not a multiple of 32
    empty = np.zeros((h, w), bool)
    full = np.ones((h, w), bool)
    one = empty.copy()
    one[h - 1, w - 1] = True
    first = empty.copy()
    first[0, 0] = True
    row_end = empty.copy()
    row_end[5, 31:34] = True  # straddles a word boundary
    stack = np.stack([empty, full, one, first, row_end])
    r = _check(stack, stack, ctx)
    assert r.iou[0, 0] == 0.0  # both empty: IoU defined as 0
    np.testing.assert_array_equal(np.diag(r.iou)[1:], 1.0)


def test_dtypes_and_values(ctx):
    rng = np.random.default_rng(3)
    a = rng.integers(0, 4, (3, 9, 40)).astype(np.uint8)  # any non-zero = inside
    b = (rng.random((2, 9, 40)) < 0.5).astype(np.int32)
    r = _check(a, b, ctx)
    r2 = K.mask_iou(a.astype(np.float32), b.astype(bool), ctx=ctx)
    np.testing.assert_array_equal(r.intersection, r2.intersection)


def test_empty_stacks(ctx):
    a = np.zeros((0, 8, 8), bool)
    b = np.ones((3, 8, 8), bool)
    r = K.mask_iou(a, b, ctx=ctx)
    assert r.iou.shape == (0, 3) and r.intersection.shape == (0, 3)
    assert K.mask_iou(b, a, ctx=ctx).iou.shape == (3, 0)
    assert not K.union(a, ctx=ctx).any() and K.union(a, ctx=ctx).shape == (8, 8)


def test_size_mismatch_is_a_clear_error(ctx):
    with pytest.raises(InputError, match=r"differ in size: 8x8 .* 8x9"):
        K.mask_iou(np.zeros((1, 8, 8), bool), np.zeros((1, 8, 9), bool), ctx=ctx)
    with pytest.raises(InputError, match="NaN"):
        K.mask_iou(np.full((1, 2, 2), np.nan), np.zeros((1, 2, 2)), ctx=ctx)
    with pytest.raises(InputError, match="shape"):
        K.mask_iou(np.zeros((1, 1, 2, 2)), np.zeros((1, 2, 2)), ctx=ctx)


def test_iou_with_target_and_union(ctx):
    rng = np.random.default_rng(5)
    masks = rng.random((7, 30, 50)) < 0.2
    target = rng.random((30, 50)) < 0.4
    got = K.iou_with_target(masks, target, ctx=ctx)
    np.testing.assert_allclose(got, mask_iou_oracle(masks, target[None])[3][:, 0], atol=1e-12)
    np.testing.assert_array_equal(K.union(masks, ctx=ctx), masks.any(0))


def test_chunking_over_bindings_and_dispatch_limits(small_ctx):
    """4 KiB bindings and 7 workgroups per dimension force every split:
    masks per chunk, rows per chunk, and output rows per dispatch."""
    rng = np.random.default_rng(7)
    h, w = 70, 300  # one mask = 70 rows x 10 words = 2800 bytes; rows split too
    a = rng.random((19, h, w)) < 0.1
    b = rng.random((11, h, w)) < 0.1
    a[3] = False
    b[4, :, :] = False
    b[4, 69, 299] = True
    p = K.pack(a, ctx=small_ctx)
    chunks = K.device_chunks(p, small_ctx)  # uploaded at packing on the gpu path, on first use on the cpu path
    assert len(chunks) > 1 and all(c.words.size <= 4096 for c in chunks)
    _check(a, b, small_ctx)
    np.testing.assert_array_equal(K.union(a, ctx=small_ctx), a.any(0))
    big_rows = rng.random((2, 40, 1100)) < 0.05  # one row = 35 words; 40 rows > 4 KiB
    _check(big_rows, big_rows[::-1], small_ctx)


def test_device_masks_are_packed_on_the_gpu(ctx, small_ctx):
    rng = np.random.default_rng(11)
    n, h, w = 5, 21, 45
    m = (rng.random((n, h, w)) < 0.3).astype(np.uint32) * rng.integers(1, 9, (n, h, w)).astype(np.uint32)
    m[2] = 0
    for c in (ctx, small_ctx):
        pad = np.zeros(3, np.uint32)  # an offset that is not binding-aligned
        buf = c.buffer(np.concatenate([pad, m.ravel()]))
        dm = K.DeviceMasks(buf, n, h, w, offset=12)
        packed = K.pack(dm, ctx=c)
        np.testing.assert_array_equal(K.to_host(packed, ctx=c), K.pack_bits(m))
        np.testing.assert_array_equal(K.unpack_bits(K.to_host(packed, ctx=c), w), m != 0)
        boxes = np.concatenate([ch.boxes_host for ch in packed.chunks if ch.r0 == 0])
        np.testing.assert_array_equal(boxes[:, :2] != 0, K._boxes(K.pack_bits(m))[:, :2] != 0)
        b = rng.random((3, h, w)) < 0.4
        r = K.mask_iou(dm, b, ctx=c)
        inter, aa, ab, iou = mask_iou_oracle(m, b)
        np.testing.assert_array_equal(r.intersection, inter)
        np.testing.assert_array_equal(r.area_a, aa)
        np.testing.assert_array_equal(K.union(dm, ctx=c), m.any(0))


def test_pack_bits_layout():
    m = np.zeros((1, 2, 40), bool)
    m[0, 0, 0] = m[0, 0, 33] = m[0, 1, 39] = True
    p = K.pack_bits(m)
    assert p.shape == (1, 2, 2)
    assert p[0, 0, 0] == 1 and p[0, 0, 1] == 2 and p[0, 1, 1] == 1 << 7
    np.testing.assert_array_equal(K.unpack_bits(p, 40), m)


masks_strategy = st.integers(1, 40).flatmap(
    lambda w: st.integers(1, 12).flatmap(
        lambda h: st.tuples(
            st.lists(st.lists(st.booleans(), min_size=h * w, max_size=h * w), min_size=1, max_size=4),
            st.just((h, w)),
        )
    )
)


@settings(max_examples=25, deadline=None)
@given(masks_strategy)
def test_iou_properties(ctx, data):
    rows, (h, w) = data
    m = np.array(rows, bool).reshape(len(rows), h, w)
    r = K.mask_iou(m, m, ctx=ctx)
    assert np.all((r.iou >= 0) & (r.iou <= 1))
    np.testing.assert_allclose(r.iou, r.iou.T, atol=0)  # symmetric
    nonempty = m.reshape(len(m), -1).any(1)
    np.testing.assert_array_equal(np.diag(r.iou)[nonempty], 1.0)  # IoU(a, a) = 1
    np.testing.assert_array_equal(np.diag(r.iou)[~nonempty], 0.0)


@pytest.mark.slow
def test_large_frames_4000x3000(ctx):
    rng = np.random.default_rng(13)
    h, w = 3000, 4000
    a = np.zeros((3, h, w), bool)
    a[0, 100:2000, 50:3000] = True
    a[1, 2999, 3999] = True
    a[2] = rng.random((h, w)) < 0.01
    b = np.zeros((2, h, w), bool)
    b[0, 1500:2999, 2000:3999] = True
    b[1] = rng.random((h, w)) < 0.5
    r = K.mask_iou(a, b, ctx=ctx)
    inter = np.array([[np.count_nonzero(x & y) for y in b] for x in a])
    np.testing.assert_array_equal(r.intersection, inter)


@pytest.mark.slow
def test_stack_over_one_real_binding(ctx):
    """90 masks of 4000x3000 pack to 135 MB, more than lavapipe's 128 MiB binding."""
    h, w, n = 3000, 4000, 90
    assert n * h * K.row_words(w) * 4 > ctx.max_binding_bytes
    a = np.zeros((n, h, w), bool)
    for k in range(n):
        a[k, (k * 31) % h : (k * 31) % h + 40, (k * 43) % w : (k * 43) % w + 50] = True
    a[n - 1, h - 1, w - 1] = True
    b = a[[n - 1, 0, 45]]
    p = K.pack(a, ctx=ctx)
    assert len(K.device_chunks(p, ctx)) >= 2
    r = K.mask_iou(p, b, ctx=ctx)
    inter = np.array([[np.count_nonzero(x & y) for y in b] for x in a])
    np.testing.assert_array_equal(r.intersection, inter)
    np.testing.assert_array_equal(r.area_a, a.reshape(n, -1).sum(1))


def test_area_kernel_and_host_popcount_agree(ctx, small_ctx):
    """Areas come from the packing step's popcount (numpy >= 2) or from the GPU
    area kernel (device masks, older numpy): both equal the oracle."""
    rng = np.random.default_rng(12)
    a = rng.random((5, 37, 70)) < 0.4
    a[0] = False
    for c in (ctx, small_ctx):
        p = K.pack(a, ctx=c)
        want = mask_iou_oracle(a, a[:1])[1]
        if p.areas_host is not None:
            np.testing.assert_array_equal(p.areas_host, want)
        p.areas_host = None  # force the GPU kernel
        np.testing.assert_array_equal(K.areas(p, ctx=c), want)


@pytest.mark.parametrize("shape", [(1, 1), (9, 33), (30, 64), (17, 95)])
def test_take_equals_packing_the_selected_masks(ctx, shape):
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    m = rng.random((6, *shape)) < 0.3
    m[2] = False  # an empty mask (zero box)
    p = K.pack(m, ctx=ctx)
    for index in ([4, 0, 2], [], [5], [1, 1, 3], list(range(6))):
        sub, want = K.take(p, index, m, ctx=ctx), K.pack(m[np.asarray(index, np.int64)], ctx=ctx)
        np.testing.assert_array_equal(K.to_host(sub, ctx=ctx), K.to_host(want, ctx=ctx))
        np.testing.assert_array_equal(sub.boxes_host, want.boxes_host)
        np.testing.assert_array_equal(K.areas(sub, ctx=ctx), K.areas(want, ctx=ctx))
        other = rng.random((3, *shape)) < 0.5
        np.testing.assert_array_equal(K.mask_iou(sub, other, ctx=ctx).iou, K.mask_iou(want, other, ctx=ctx).iou)


def test_take_from_device_packed_masks_needs_the_source(ctx):
    m = np.zeros((3, 4, 40), np.uint32)
    m[1, 1:3, 5:30] = 1
    packed = K.pack(K.DeviceMasks(ctx.buffer(m.ravel()), 3, 4, 40), ctx=ctx)
    np.testing.assert_array_equal(K.to_host(K.take(packed, [1, 0], m, ctx=ctx), ctx=ctx), K.pack_bits(m[[1, 0]]))
    with pytest.raises(ValueError, match="packed from"):
        K.take(packed, [0], ctx=ctx)


def test_pack_memo_packs_each_array_once(ctx):
    rng = np.random.default_rng(3)
    a = rng.random((4, 10, 50)) < 0.4
    memo = K.PackMemo(ctx)
    first = memo.pack(a)
    assert memo.pack(a) is first  # the same array: the same pack
    copy = a.copy()
    assert memo.pack(copy) is not first  # equal content, another array: packed on its own
    np.testing.assert_array_equal(K.to_host(memo.pack(copy), ctx=ctx), K.pack_bits(a))
    assert memo.pack(first) is first  # a PackedMasks passes through
