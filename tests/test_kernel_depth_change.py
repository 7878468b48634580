"""Depth-change kernel (dD, histogram, changed pixels) against its numpy oracle."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from r360gpu.errors import InputError
from r360gpu.kernels import depth_change as K

from oracles import depth_change_oracle, no_depth_oracle


@pytest.fixture(autouse=True, params=["gpu-histo", "gpu-histo_private", "cpu"])
def histogram_flavour(request, monkeypatch):
    """Every test runs the kernel with both histogram entry points (GPU and CPU flavour), and the
    host path that CPU adapters take for numpy inputs."""
    backend, _, entry = request.param.partition("-")
    monkeypatch.setenv("R360GPU_DEPTH_CHANGE", backend)
    monkeypatch.setenv("R360GPU_HISTOGRAM", entry or "histo")
    return request.param


def test_backend_default_follows_the_adapter(ctx, monkeypatch):
    monkeypatch.delenv("R360GPU_DEPTH_CHANGE")
    cpu = ctx.adapter_info["adapter_type"] == "CPU"
    assert ctx.kernel_backend("depth_change") == ("cpu" if cpu else "gpu")
    pre, post = np.ones((3, 4), np.float32), np.full((3, 4), 2, np.float32)
    stage = K.delta_histogram(pre, post, ctx=ctx)
    assert (stage.bins_host is not None) == cpu and (not stage.chunks) == cpu


def test_flavour_is_chosen_by_adapter_type(ctx, monkeypatch):
    monkeypatch.delenv("R360GPU_HISTOGRAM")
    cpu = ctx.adapter_info["adapter_type"] == "CPU"
    assert K.histogram_entry(ctx) == ("histo_private" if cpu else "histo")


def _run(ctx, pre, post, mask, t):
    stage = K.delta_histogram(pre, post, ctx=ctx)
    res = K.changed_in_mask(stage, mask, t, ctx=ctx)
    d, lo, hi, hist, changed, n_in, n_m = depth_change_oracle(pre, post, mask, t)
    assert (stage.lo, stage.hi) == (lo, hi)
    np.testing.assert_array_equal(stage.hist, hist)
    np.testing.assert_array_equal(res.changed, changed)
    assert (res.n_changed_in_mask, res.n_mask) == (n_in, n_m)
    assert res.n_no_depth_in_mask == no_depth_oracle(post, mask)
    return stage, res


def _scene(rng, h, w):
    pre = rng.uniform(0.5, 8.0, (h, w)).astype(np.float32)
    post = pre.copy()
    sel = rng.random((h, w)) < 0.3
    post[sel] += rng.uniform(0.0, 3.0, sel.sum()).astype(np.float32)
    return pre, post, rng.random((h, w)) < 0.4


@pytest.mark.parametrize("shape", [(1, 1), (1, 33), (5, 7), (48, 64), (45, 67), (129, 3)])
def test_random_depths_match_oracle(ctx, shape):
    rng = np.random.default_rng(sum(shape))
    pre, post, mask = _scene(rng, *shape)
    for t in (0.0, 17.5, 127.0, 254.0, 255.0):
        _run(ctx, pre, post, mask, t)


def test_missing_and_non_finite_depths_give_zero_change(ctx):
    rng = np.random.default_rng(2)
    pre, post, mask = _scene(rng, 31, 45)
    pre[0, :10] = 0
    post[1, :10] = np.nan
    post[2, :10] = np.inf
    pre[3, :10] = -np.inf
    pre[4, :10] = -2.0
    stage, res = _run(ctx, pre, post, mask, 3.0)
    assert not res.changed[:5, :10].any()
    assert np.isfinite(stage.lo) and np.isfinite(stage.hi)


@pytest.mark.parametrize("shape", [(1, 1), (3, 1), (31, 45), (70, 50)])
def test_no_depth_after_removal_in_the_mask_is_counted(ctx, small_ctx, shape):
    """A see-through hole: D_post missing (0, NaN, +/-Inf, negative) inside M, whatever D_pre is; counted
    by both passes as the oracle counts it (only where M is), never as changed; 4 KiB bindings split
    the 70 x 50 view into row chunks whose no-depth words must line up with the mask's."""
    rng = np.random.default_rng(sum(shape) + 3)
    pre, post, mask = _scene(rng, *shape)
    flat = post.reshape(-1)
    holes = rng.random(flat.size) < 0.35
    flat[holes] = rng.choice(np.array([0.0, np.nan, np.inf, -np.inf, -1.5], np.float32), int(holes.sum()))
    pre.reshape(-1)[rng.random(flat.size) < 0.1] = 0.0  # missing before too: still no depth after removal
    for c in (ctx, small_ctx):
        for m in (mask, np.zeros_like(mask), np.ones_like(mask)):
            stage = K.delta_histogram(pre, post, ctx=c)
            res = K.changed_in_mask(stage, m, 0.0, ctx=c)
            assert res.n_no_depth_in_mask == no_depth_oracle(post, m)
            assert not (res.changed & ~(np.isfinite(post) & (post > 0))).any()
    one = np.full(shape, 2.0, np.float32)
    one.flat[-1] = np.nan  # exactly one hole, in the last pixel (the last, partly filled word)
    res = K.changed_in_mask(K.delta_histogram(one * 2, one, ctx=ctx), np.ones(shape, bool), 0.0, ctx=ctx)
    assert res.n_no_depth_in_mask == 1


def test_constant_and_identical_depths(ctx):
    d = np.full((9, 40), 2.5, np.float32)
    stage, res = _run(ctx, d, d, np.ones_like(d, bool), 127.0)
    assert stage.lo == stage.hi == 0.0 and stage.hist[0] == d.size and res.n_changed_in_mask == 0
    empty = np.zeros((9, 40), np.float32)
    _run(ctx, empty, empty, np.zeros_like(d, bool), 0.0)


def test_empty_mask_counts_zero(ctx):
    rng = np.random.default_rng(4)
    pre, post, _ = _scene(rng, 20, 20)
    _, res = _run(ctx, pre, post, np.zeros((20, 20), bool), 10.0)
    assert res.n_mask == 0


def test_shape_errors(ctx):
    with pytest.raises(InputError, match="D_pre is 4x5 but D_post is 4x6"):
        K.delta_histogram(np.ones((4, 5)), np.ones((4, 6)), ctx=ctx)
    stage = K.delta_histogram(np.ones((4, 5)), np.ones((4, 5)), ctx=ctx)
    with pytest.raises(InputError, match="target mask is 4x4"):
        K.changed_in_mask(stage, np.ones((4, 4), bool), 1.0, ctx=ctx)
    with pytest.raises(InputError, match=r"shape \(H, W\)"):
        K.delta_histogram(np.ones((2, 4, 5)), np.ones((2, 4, 5)), ctx=ctx)


def test_row_chunking(small_ctx, histogram_flavour):
    """4 KiB bindings hold 1024 floats: a 70 x 50 view is split into 4 chunks (by the kernel)."""
    rng = np.random.default_rng(6)
    pre, post, mask = _scene(rng, 70, 50)
    post[69, 49] = 1e6  # the maximum sits in the last chunk
    stage, _ = _run(small_ctx, pre, post, mask, 12.25)
    assert len(stage.chunks) == (0 if histogram_flavour == "cpu" else 4)


def test_device_depth_inputs(ctx, small_ctx):
    rng = np.random.default_rng(8)
    pre, post, mask = _scene(rng, 33, 41)
    for c in (ctx, small_ctx):
        buf = c.buffer(np.concatenate([np.zeros(5, np.float32), pre.ravel(), post.ravel()]))
        dp = K.DeviceDepth(buf, 33, 41, offset=20)
        dq = K.DeviceDepth(buf, 33, 41, offset=20 + pre.nbytes)
        stage = K.delta_histogram(dp, dq, ctx=c)
        res = K.changed_in_mask(stage, mask, 40.0, ctx=c)
        _, lo, hi, hist, changed, n_in, n_m = depth_change_oracle(pre, post, mask, 40.0)
        np.testing.assert_array_equal(stage.hist, hist)
        np.testing.assert_array_equal(res.changed, changed)
        assert (res.n_changed_in_mask, res.n_mask) == (n_in, n_m)
        assert res.n_no_depth_in_mask == no_depth_oracle(post, mask)


@settings(max_examples=20, deadline=None)
@given(
    hnp.arrays(np.float32, st.tuples(st.integers(1, 9), st.integers(1, 40)),
               elements=st.one_of(st.floats(-1, 1e4, width=32), st.sampled_from([0.0, np.nan, np.inf, -np.inf]))),
    st.floats(0, 255),
)
def test_histogram_property(ctx, pre, t):
    post = pre[::-1].copy()
    stage, res = _run(ctx, pre, post, np.ones_like(pre, bool), t)
    assert stage.hist.sum() == pre.size


@pytest.mark.slow
def test_4000x3000_view(ctx):
    rng = np.random.default_rng(10)
    pre, post, mask = _scene(rng, 3000, 4000)
    _run(ctx, pre, post, mask, 100.0)


@pytest.mark.parametrize("shape", [(1, 1), (45, 67), (70, 50)])
def test_batched_methods_equal_the_oracle(ctx, small_ctx, shape):
    """One D_pre against several D_post (a view's methods) in one batch, incl.
    identical, all-missing and NaN/Inf posts, and row chunks beyond one binding."""
    rng = np.random.default_rng(sum(shape) + 11)
    pre, post, mask = _scene(rng, *shape)
    bad = post.copy()
    bad.flat[:: 3] = np.nan
    bad.flat[1:: 5] = np.inf
    posts = [post, pre.copy(), np.zeros_like(pre), bad, post * 2]
    ts = [0.0, 17.5, 127.0, 254.0, 3.5]
    for c in (ctx, small_ctx):
        stages = K.delta_histograms(pre, posts, ctx=c)
        res = K.changed_in_masks(stages, mask, ts, ctx=c)
        for st, r, d, t in zip(stages, res, posts, ts):
            _, lo, hi, hist, changed, n_in, n_m = depth_change_oracle(pre, d, mask, t)
            assert (st.lo, st.hi) == (lo, hi)
            np.testing.assert_array_equal(st.hist, hist)
            np.testing.assert_array_equal(r.changed, changed)
            assert (r.n_changed_in_mask, r.n_mask) == (n_in, n_m)
            assert r.n_no_depth_in_mask == no_depth_oracle(d, mask)
    assert K.delta_histograms(pre, [], ctx=ctx) == [] and K.changed_in_masks([], mask, [], ctx=ctx) == []
    with pytest.raises(InputError, match="D_post is"):
        K.delta_histograms(pre, [post, post[:, :-1] if shape[1] > 1 else post[:0]], ctx=ctx)


def test_acc_depth_views_equal_single_views(ctx):
    from r360gpu.metrics.geometric import acc_depth_view, acc_depth_views

    rng = np.random.default_rng(4)
    pre, post, mask = _scene(rng, 33, 47)
    posts = [post, pre, post + 1]
    for compat in (False, True):
        many = acc_depth_views(pre, posts, mask, compat=compat, ctx=ctx)
        for v, d in zip(many, posts):
            one = acc_depth_view(pre, d, mask, compat=compat, ctx=ctx)
            assert v.summary() == one.summary()
            np.testing.assert_array_equal(v.changed, one.changed)
            np.testing.assert_array_equal(v.hist, one.hist)


@pytest.mark.parametrize("t", [254.99999999999997, 254.5, 0.9999999999999999, -0.5, -np.inf, np.inf, np.nan, 1e9])
def test_split_just_below_a_whole_bin(ctx, t):
    """A float64 split that rounds up in float32 must not move the changed set."""
    pre = np.arange(1, 301, dtype=np.float32).reshape(10, 30)
    post = np.zeros_like(pre) + 0.5
    _run(ctx, pre, post, np.ones_like(pre, bool), t)

