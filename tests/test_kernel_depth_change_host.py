"""The depth-change host path (what CPU adapters take) beyond what the shared kernel tests cover."""
from __future__ import annotations

import numpy as np

from r360gpu.kernels import depth_change as K

from oracles import depth_change_oracle


def test_host_histogram_over_several_count_chunks(ctx, monkeypatch):
    """cv2.calcHist counts in float32, so the host path counts at most _HIST_CHUNK pixels per call;
    with a chunk far smaller than the image (not a divisor of it) the counts still equal the oracle's."""
    monkeypatch.setenv("R360GPU_DEPTH_CHANGE", "cpu")
    monkeypatch.setattr(K, "_HIST_CHUNK", 97)
    rng = np.random.default_rng(11)
    h, w = 45, 67
    pre = rng.uniform(0.5, 8.0, (h, w)).astype(np.float32)
    post = pre.copy()
    sel = rng.random((h, w)) < 0.3
    post[sel] += rng.uniform(0.0, 3.0, sel.sum()).astype(np.float32)
    post[0, :5] = np.nan  # missing depth counts as dD = 0
    stage = K.delta_histogram(pre, post, ctx=ctx)
    assert stage.bins_host is not None
    _, lo, hi, hist, _, _, _ = depth_change_oracle(pre, post, rng.random((h, w)) < 0.4, 100.0)
    assert (stage.lo, stage.hi) == (lo, hi)
    np.testing.assert_array_equal(stage.hist, hist)
    assert stage.hist.sum() == h * w
