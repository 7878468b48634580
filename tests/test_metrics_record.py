"""The per-view record: built from real measurements, strict JSON, lossless round trip."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.fidelity import fidelity_view
from r360gpu.metrics.geometric import acc_depth_view
from r360gpu.metrics.record import SCHEMA, ViewRecord
from r360gpu.metrics.semantic import semantic_view
from r360gpu.metrics.structural import structural_view
from r360gpu.probes.base import MaskSet, SemanticPrediction


def _record(ctx):
    rng = np.random.default_rng(5)
    h, w = 24, 32
    t = np.zeros((h, w), bool)
    t[6:18, 8:24] = True
    pred = SemanticPrediction(t[None], [0.8], ["chair"], "gsam2")
    sem_a = semantic_view(pred, SemanticPrediction.empty(h, w, "gsam2"), t, ctx=ctx)
    left = t.copy()
    left[:, 12:] = False
    sem_b = semantic_view(SemanticPrediction(t[None], [0.7], ["chair"], "ovseg"), left, t, ctx=ctx)
    a = MaskSet(np.stack([t, rng.random((h, w)) < 0.5]), np.array([0.9, 0.3]), "sam2")
    st = structural_view(a, MaskSet(t[None], None, "sam2"), t, mode="reference", ctx=ctx)
    d_pre = np.full((h, w), 3.0, np.float32)
    d_pre[t] = 1.0
    geo = acc_depth_view(d_pre, np.full((h, w), 3.0, np.float32), t, ctx=ctx)
    img = rng.random((h, w, 3))
    fid = fidelity_view(img, img)  # identical: PSNR = inf
    probes = [
        {"name": "gsam2", "kind": "semantic", "models": {"g.onnx": "ab" * 32}, "params": {"box_threshold": 0.35}},
        {"name": "sam2", "kind": "structural", "models": {}, "params": {"points_per_side": 32}},
    ]
    return ViewRecord.build(
        "00012", "sofa", "GC", probes=probes, semantic=[sem_a, sem_b], structural=[st], geometric=geo, fidelity=fid
    )


def test_round_trip_is_lossless_strict_json(ctx):
    rec = _record(ctx)
    assert set(rec.semantic) == {"gsam2", "ovseg"} and set(rec.structural) == {"sam2"}
    assert rec.geometric["acc_depth"] == 1.0 and rec.fidelity.psnr == math.inf
    text = json.dumps(rec.to_dict(), allow_nan=False)
    back = ViewRecord.from_dict(json.loads(text))
    assert back == rec
    assert back.fidelity.psnr == math.inf
    assert json.loads(text)["schema"] == SCHEMA


def test_bad_records(ctx):
    d = _record(ctx).to_dict()
    with pytest.raises(InputError, match="schema"):
        ViewRecord.from_dict({**d, "schema": "other/9"})
    with pytest.raises(InputError, match="scene"):
        ViewRecord.from_dict({k: v for k, v in d.items() if k != "scene"})
    sem = next(iter(_record(ctx).semantic.values()))
    with pytest.raises(InputError, match="two readings"):
        ViewRecord.build("v", "s", "m", semantic=[sem, sem])
