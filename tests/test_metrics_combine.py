"""Several probes per axis: per-probe readings and the per-view "most alarming" one."""
from __future__ import annotations

import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.metrics.combine import most_alarming_semantic, most_alarming_structural
from r360gpu.metrics.semantic import SemanticView
from r360gpu.metrics.structural import StructuralView


def _sem(pre, post, probe, area=100):
    return SemanticView(pre, post, area == 0, area, 0, 0, 0, 0, 1, 1, probe)


def _str(sim, probe, mode="reference", area=100):
    return StructuralView(sim, 1, 1, (0,), (0,), (), (), area == 0, area, mode, probe)


def test_semantic_worst_is_max_iou_post():
    a = [_sem(0.9, 0.1, "a"), _sem(0.8, 0.6, "a"), _sem(0.7, 0.2, "a")]
    b = [_sem(0.6, 0.4, "b"), _sem(0.9, 0.1, "b"), _sem(0.5, 0.2, "b")]
    c = most_alarming_semantic({"a": a, "b": b}, xis=(0.3, 0.5))
    assert c.worst_probe == ["b", "a", "a"]  # view 3 ties at 0.2: the first probe wins
    assert [v.iou_post for v in c.worst] == [0.4, 0.6, 0.2]
    assert c.per_probe["a"].acc_seg[0.3] == pytest.approx(2 / 3)
    assert c.per_probe["b"].acc_seg[0.3] == pytest.approx(2 / 3)
    # Combined: only view 3 is below 0.3 for every probe.
    assert c.combined.s_sem == pytest.approx(1 / 3)
    assert c.combined.acc_seg[0.5] == pytest.approx(2 / 3)
    # The chosen view keeps its own probe's IoU_pre: drops 0.2, 0.2, 0.5.
    assert c.combined.iou_drop == pytest.approx(0.3)
    # Never better than any single probe, at any threshold.
    for x in (0.3, 0.5):
        assert c.combined.acc_seg[x] <= min(s.acc_seg[x] for s in c.per_probe.values())
    d = json.loads(json.dumps(c.to_dict(), allow_nan=False))
    assert d["worst_probe"] == ["b", "a", "a"]


def test_structural_orientation_per_mode():
    ref = most_alarming_structural({"p": [_str(0.8, "p"), _str(0.2, "p")], "q": [_str(0.5, "q"), _str(0.3, "q")]})
    assert ref.worst_probe == ["q", "p"] and [v.sim_sam for v in ref.worst] == [0.5, 0.2]
    assert ref.combined.s_str == pytest.approx(0.35)
    free = most_alarming_structural(
        {
            "p": [_str(0.8, "p", "reference_free"), _str(0.2, "p", "reference_free")],
            "q": [_str(0.5, "q", "reference_free"), _str(0.3, "q", "reference_free")],
        }
    )
    # Without a reference s_str = 1 - sim: the highest sim is the most alarming.
    assert free.worst_probe == ["p", "q"] and [v.sim_sam for v in free.worst] == [0.8, 0.3]
    assert free.combined.s_str == pytest.approx(1 - 0.55)
    assert free.combined.s_str <= min(s.s_str for s in free.per_probe.values())
    assert free.to_dict()["mode"] == "reference_free"


def test_empty_targets_follow_the_summary_rule():
    a = [_sem(0.9, 0.9, "a", area=0), _sem(0.9, 0.1, "a")]
    b = [_sem(0.0, 0.0, "b", area=0), _sem(0.9, 0.2, "b")]
    c = most_alarming_semantic({"a": a, "b": b})
    assert c.combined.n_scored == 1 and c.combined.n_empty_target == 1 and c.combined.s_sem == 1.0


def test_misaligned_inputs_are_errors():
    with pytest.raises(InputError, match="different numbers"):
        most_alarming_semantic({"a": [_sem(1, 0, "a")], "b": []})
    with pytest.raises(InputError, match="not aligned"):
        most_alarming_semantic({"a": [_sem(1, 0, "a", area=10)], "b": [_sem(1, 0, "b", area=11)]})
    with pytest.raises(InputError, match="mix modes"):
        most_alarming_structural({"a": [_str(1, "a")], "b": [_str(1, "b", "reference_free")]})
    with pytest.raises(InputError):
        most_alarming_structural({"a": [], "b": []})
    with pytest.raises(InputError):
        most_alarming_semantic({})


def test_single_probe_is_its_own_worst():
    views = [_sem(0.5, x, "only") for x in np.linspace(0, 1, 5)]
    c = most_alarming_semantic({"only": views})
    assert c.combined == c.per_probe["only"]
