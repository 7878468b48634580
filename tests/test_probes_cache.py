"""On-disk probe cache: hits, invalidation, corrupted files, exact round trips."""
from __future__ import annotations

import math

import numpy as np
import pytest

from r360gpu.errors import InputError, R360Warning
from r360gpu.probes.base import MaskSet, ProbeView, SemanticPrediction, SemanticProbe, StructuralProbe
from r360gpu.probes.cache import (
    CachedSemanticProbe,
    CachedStructuralProbe,
    ProbeCache,
    cache_key,
    cached,
    canonical_json,
    image_digest,
)


class ThresholdSemantic(SemanticProbe):
    """Deterministic stand-in for a model probe: instances = channel > threshold."""

    def __init__(self, name="fake-sem", threshold=100, model_hash="a" * 64):
        self._name, self.threshold, self.model_hash = name, threshold, model_hash
        self.calls: list[tuple[list[str], str]] = []

    @property
    def name(self):
        return self._name

    def params(self):
        return {"threshold": self.threshold, "channels": (0, 1)}

    def model_hashes(self):
        return {"fake.onnx": self.model_hash}

    def predict(self, views, prompt):
        self.calls.append(([v.name for v in views], prompt))
        out = []
        for v in views:
            masks = np.stack([v.image[..., c] > self.threshold for c in (0, 1)])
            scores = np.array([v.image[..., 0].mean() / 255, 0.25], np.float32)
            out.append(SemanticPrediction(masks, scores, [prompt, f"{prompt} part"], self.name))
        return out


class BlobStructural(StructuralProbe):
    def __init__(self, with_scores=True):
        self.with_scores = with_scores
        self.calls = 0

    @property
    def name(self):
        return "fake-struct"

    def params(self):
        return {"scores": self.with_scores}

    def predict(self, views):
        self.calls += 1
        out = []
        for v in views:
            g = v.image[..., 2]
            masks = np.stack([g > 200, g < 50, np.zeros_like(g, bool)])
            out.append(MaskSet(masks, np.array([0.9, 0.8, 0.1], np.float32) if self.with_scores else None, self.name))
        return out


def _views(n=3, h=13, w=9, seed=0):
    rng = np.random.default_rng(seed)
    return [ProbeView(f"{i:05d}", rng.integers(0, 256, (h, w, 3), dtype=np.uint8), "post") for i in range(n)]


def _same(a, b):
    assert a.masks.shape == b.masks.shape and np.array_equal(a.masks, b.masks)
    assert a.probe == b.probe
    if isinstance(a, SemanticPrediction):
        assert a.labels == b.labels
        np.testing.assert_array_equal(a.scores, b.scores)
    else:
        assert (a.scores is None) == (b.scores is None)
        if a.scores is not None:
            np.testing.assert_array_equal(a.scores, b.scores)


def test_semantic_hits_return_identical_results(tmp_path):
    cache = ProbeCache(tmp_path)
    probe = ThresholdSemantic()
    wrapped = cached(probe, cache)
    assert isinstance(wrapped, CachedSemanticProbe)
    views = _views()
    first = wrapped.predict(views, "sofa")
    assert probe.calls == [([v.name for v in views], "sofa")]  # one batch for all misses
    assert (cache.hits, cache.misses) == (0, 3)
    second = wrapped.predict(views, "sofa")
    assert len(probe.calls) == 1
    assert cache.hits == 3
    for a, b in zip(first, second):
        _same(a, b)
    assert wrapped.describe() == probe.describe()
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]


def test_only_changed_image_reruns(tmp_path):
    cache = ProbeCache(tmp_path)
    probe = ThresholdSemantic()
    wrapped = cached(probe, cache)
    views = _views()
    wrapped.predict(views, "sofa")
    image = views[1].image.copy()
    image[0, 0, 0] ^= 1
    changed = [views[0], ProbeView(views[1].name, image, "post"), views[2]]
    wrapped.predict(changed, "sofa")
    assert probe.calls[-1] == ([views[1].name], "sofa")


@pytest.mark.parametrize(
    "other",
    [
        dict(name="fake-sem-2"),
        dict(threshold=101),
        dict(model_hash="b" * 64),
    ],
    ids=["probe-name", "parameter", "model-hash"],
)
def test_probe_configuration_change_misses(tmp_path, other):
    cache = ProbeCache(tmp_path)
    views = _views()
    cached(ThresholdSemantic(), cache).predict(views, "sofa")
    changed = ThresholdSemantic(**other)
    cached(changed, cache).predict(views, "sofa")
    assert len(changed.calls) == 1 and len(changed.calls[0][0]) == 3
    again = ThresholdSemantic()
    cached(again, cache).predict(views, "sofa")
    assert again.calls == []  # the original configuration still hits


def test_prompt_change_misses(tmp_path):
    cache = ProbeCache(tmp_path)
    probe = ThresholdSemantic()
    wrapped = cached(probe, cache)
    views = _views(2)
    wrapped.predict(views, "sofa")
    out = wrapped.predict(views, "table")
    assert len(probe.calls) == 2 and out[0].labels == ["table", "table part"]


@pytest.mark.parametrize("with_scores", [True, False])
def test_structural_round_trip(tmp_path, with_scores):
    cache = ProbeCache(tmp_path)
    probe = BlobStructural(with_scores)
    wrapped = cached(probe, cache)
    assert isinstance(wrapped, CachedStructuralProbe)
    views = _views(2, h=7, w=5)  # 35 pixels per mask: bit packing with a ragged tail
    first = wrapped.predict(views)
    second = wrapped.predict(views)
    assert probe.calls == 1
    for a, b in zip(first, second):
        _same(a, b)


def test_empty_results_round_trip(tmp_path):
    cache = ProbeCache(tmp_path)
    empty_sem = SemanticPrediction.empty(5, 3, "p")
    empty_set = MaskSet.empty(5, 3, "p")
    cache.store("p", "k1", empty_sem)
    cache.store("p", "k2", empty_set)
    _same(cache.load("p", "k1", "semantic"), empty_sem)
    _same(cache.load("p", "k2", "masks"), empty_set)
    nan = SemanticPrediction(np.ones((1, 2, 2), bool), [math.nan], ["x"], "p")
    cache.store("p", "k3", nan)
    assert np.isnan(cache.load("p", "k3", "semantic").scores[0])


def _entry_path(cache, views, probe, prompt="sofa"):
    return cache.path_for(probe.name, cache_key(views[0].image, probe.name, probe.describe(), prompt))


@pytest.mark.parametrize(
    "damage",
    [
        lambda p: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]),
        lambda p: p.write_bytes(b"not an npz at all"),
        lambda p: p.write_bytes(b""),
    ],
    ids=["truncated", "garbage", "empty"],
)
def test_corrupted_file_is_a_miss_with_warning(tmp_path, damage):
    cache = ProbeCache(tmp_path)
    probe = ThresholdSemantic()
    wrapped = cached(probe, cache)
    views = _views(2)
    first = wrapped.predict(views, "sofa")
    path = _entry_path(cache, views, probe)
    assert path.is_file()
    damage(path)
    with pytest.warns(R360Warning, match="corrupted probe cache file") as record:
        again = wrapped.predict(views, "sofa")
    assert str(path) in str(record[0].message)
    assert probe.calls[-1] == ([views[0].name], "sofa")
    assert cache.corrupt == 1
    _same(first[0], again[0])
    wrapped.predict(views, "sofa")  # rewritten: hits now
    assert len(probe.calls) == 2


def test_unwritable_cache_warns_and_still_returns(tmp_path):
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache directory should be")
    probe = ThresholdSemantic()
    wrapped = cached(probe, ProbeCache(blocker))
    with pytest.warns(R360Warning, match="cannot write the probe cache") as record:
        out = wrapped.predict(_views(2), "sofa")
    assert len(record) == 1
    _same(out[1], probe.predict(_views(2), "sofa")[1])


def test_entry_under_wrong_key_or_kind_is_rejected(tmp_path):
    cache = ProbeCache(tmp_path)
    pred = SemanticPrediction(np.ones((1, 3, 3), bool), [0.5], ["x"], "p")
    cache.store("p", "aa11", pred)
    # Copy the file to another key's place: the stored key no longer matches.
    src = cache.path_for("p", "aa11")
    dst = cache.path_for("p", "aa22")
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(src.read_bytes())
    with pytest.warns(R360Warning, match="does not match"):
        assert cache.load("p", "aa22", "semantic") is None
    with pytest.warns(R360Warning, match="expected 'masks'"):
        assert cache.load("p", "aa11", "masks") is None
    assert cache.load("p", "zz99", "semantic") is None  # plain miss: no warning
    assert cache.corrupt == 2


def test_cache_key_recipe():
    img = np.zeros((4, 4, 3), np.uint8)
    cfg = {"name": "p", "params": {"a": 1, "b": (1, 2)}}
    cfg_reordered = {"params": {"b": [1, 2], "a": 1}, "name": "p"}
    k = cache_key(img, "p", cfg, "sofa")
    assert k == cache_key(img.copy(), "p", cfg_reordered, "sofa")
    assert k != cache_key(img, "q", cfg, "sofa")
    assert k != cache_key(img, "p", cfg, "table")
    assert k != cache_key(img, "p", cfg, None)
    assert k != cache_key(img, "p", {"name": "p", "params": {"a": 2, "b": (1, 2)}}, "sofa")
    # Same bytes, different dtype or shape: different images.
    assert image_digest(img) != image_digest(img.reshape(4, 12, 1))
    assert image_digest(np.zeros(4, np.int32)) != image_digest(np.zeros(16, np.uint8))
    assert canonical_json({"b": 1, "a": [np.float32(0.5), np.int64(3)]}) == '{"a":[0.5,3],"b":1}'
    with pytest.raises(ValueError):
        canonical_json({"x": float("nan")})
    with pytest.raises(TypeError):
        canonical_json({"x": object()})


def test_probe_names_become_safe_directories(tmp_path):
    cache = ProbeCache(tmp_path)
    path = cache.path_for("../gsam2 / swin-B", "abcdef")
    assert path.parent.parent.parent == tmp_path
    assert path.name == "abcdef.npz"


def test_views_without_image_and_non_cacheable_probes(tmp_path):
    cache = ProbeCache(tmp_path)
    wrapped = cached(ThresholdSemantic(), cache)
    with pytest.raises(InputError, match="needs the rendered image of view '00001'"):
        wrapped.predict([ProbeView("00001", size=(4, 4), rendering="post")], "sofa")

    class FileProbe(ThresholdSemantic):
        cacheable = False

    plain = FileProbe()
    assert cached(plain, cache) is plain
    assert cached(ThresholdSemantic(), None).__class__ is ThresholdSemantic
    assert cached(wrapped, cache) is wrapped


def test_probe_returning_wrong_sizes_is_caught(tmp_path):
    class Broken(ThresholdSemantic):
        def predict(self, views, prompt):
            return [SemanticPrediction.empty(1, 1, self.name) for _ in views]

    with pytest.raises(RuntimeError, match="result for view"):
        cached(Broken(), ProbeCache(tmp_path)).predict(_views(1), "sofa")
    assert not any(p.suffix == ".npz" for p in tmp_path.rglob("*"))


def test_describe_shape():
    d = ThresholdSemantic().describe()
    assert d == {
        "name": "fake-sem",
        "kind": "semantic",
        "models": {"fake.onnx": "a" * 64},
        "params": {"threshold": 100, "channels": (0, 1)},
    }


def test_result_types_validate_and_union():
    m = np.zeros((2, 3, 4), np.uint8)
    m[0, 0, 0] = 1
    m[1, 2, 3] = 7
    pred = SemanticPrediction(m, [0.5, 0.25], ["a", "b"], "p")
    assert pred.masks.dtype == bool and pred.scores.dtype == np.float32
    assert pred.count == 2 and pred.size == (3, 4)
    union = pred.union()
    assert union.shape == (3, 4) and union.sum() == 2 and union[0, 0] and union[2, 3]
    empty = SemanticPrediction.empty(3, 4)
    assert empty.count == 0 and not empty.union().any() and empty.union().shape == (3, 4)
    with pytest.raises(TypeError):
        SemanticPrediction(np.zeros((1, 2, 2), np.float32), [1.0], ["a"])
    with pytest.raises(ValueError):
        SemanticPrediction(np.zeros((1, 2, 2), bool), [1.0, 2.0], ["a"])
    with pytest.raises(ValueError):
        SemanticPrediction(np.zeros((1, 2, 2), bool), [1.0], [])
    with pytest.raises(ValueError):
        MaskSet(np.zeros((2, 2), bool))
    with pytest.raises(ValueError):
        MaskSet(np.zeros((2, 2, 2), bool), [0.1])
    with pytest.raises(ValueError):
        ProbeView("v", np.zeros((4, 4), np.uint8))
    with pytest.raises(ValueError):
        ProbeView("v", np.zeros((4, 4, 3), np.uint8), size=(4, 5))
    with pytest.raises(ValueError):
        ProbeView("v", np.zeros((4, 4, 3), np.uint8), rendering="after")
    with pytest.raises(ValueError):
        ProbeView("v")
    assert ProbeView("v", size=(4, 5)).size == (4, 5)
