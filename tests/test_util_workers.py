"""The decoding worker pool: results and errors come back as if run here; off when told so."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.probes import precomputed as P
from r360gpu.util import workers


@pytest.fixture
def one_worker(monkeypatch):
    monkeypatch.setenv(workers.ENV_VAR, "1")
    yield
    workers.shutdown()


def test_call_runs_in_another_process_and_errors_come_back(one_worker, tmp_path):
    assert workers.call(os.getpid) != os.getpid()
    bad = tmp_path / "bad.json"
    bad.write_text('[{"segmentation": [[true, fals]]}]')
    with pytest.raises(InputError) as exc:
        workers.call(P.read_sam_json, bad)
    assert exc.value.path == str(bad) and "malformed JSON" in exc.value.problem


def test_zero_workers_runs_here(monkeypatch):
    monkeypatch.setenv(workers.ENV_VAR, "0")
    assert workers.workers() == 0
    assert workers.call(os.getpid) == os.getpid()


def test_default_is_off_for_library_callers_and_leaves_a_core_under_the_cli(monkeypatch):
    monkeypatch.delenv(workers.ENV_VAR, raising=False)
    monkeypatch.setattr(workers, "_allowed", False)
    assert workers.workers() == 0  # an unguarded caller's script would be re-run by each worker
    workers.allow()
    assert workers.workers() == max(0, min(2, (os.cpu_count() or 1) - 1))


def test_big_sam_json_files_are_read_in_a_worker_with_the_same_masks(one_worker, tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    masks = [rng.random((37, 53)) < p for p in (0.2, 0.6)]
    d = tmp_path / "sam"
    d.mkdir()
    (d / "v1.json").write_text(json.dumps([{"segmentation": m.tolist(), "predicted_iou": 0.9} for m in masks]))
    here = P.SamJsonDir(d).read("v1", "p")
    calls = []
    real = workers.call
    monkeypatch.setattr(workers, "call", lambda fn, *a, **k: calls.append(fn) or real(fn, *a, **k))
    monkeypatch.setattr(P, "WORKER_MIN_BYTES", 1)
    there = P.SamJsonDir(d).read("v1", "p")
    assert calls == [P.read_sam_json]
    np.testing.assert_array_equal(there.masks, np.stack(masks))
    np.testing.assert_array_equal(there.masks, here.masks)
    np.testing.assert_array_equal(there.scores, here.scores)
    assert there.probe == here.probe == "p"
