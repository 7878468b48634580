"""On-disk cache of probe outputs, so re-scoring never re-runs a probe on an unchanged image.

Key: SHA-256 of the canonical JSON of
``{"format", "code": <r360gpu's code digest>, "image": <image content hash>, "probe": <name>,
"config": <probe.describe()>, "prompt": <prompt or null>}``.  The code digest
(:func:`r360gpu.util.code_id.code_digest`) makes an output computed by other
r360gpu code (a pulled checkout, a local edit) a miss.  The image content
hash covers the decoded pixels (dtype, shape and bytes), so the same
rendering hits whether it came from a file or from the renderer; the
configuration is the probe's full ``describe()`` (name, model file hashes,
parameters), so changing any of them misses.

Layout: ``<root>/<probe name>/<key[:2]>/<key>.npz``, one compressed npz per
(view image, probe, configuration, prompt), written atomically.  Masks are
bit-packed with ``np.packbits``.  A file that cannot be read back, or whose
contents do not check out, is a miss with an :class:`R360Warning`, and is
overwritten by the fresh result.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError, R360Warning
from r360gpu.util import code_id
from r360gpu.probes.base import (
    MaskSet,
    Probe,
    ProbeView,
    SemanticPrediction,
    SemanticProbe,
    StructuralProbe,
    check_results,
)
from r360gpu.util.atomic import write_bytes

__all__ = [
    "CACHE_FORMAT",
    "canonical_json",
    "image_digest",
    "cache_key",
    "ProbeCache",
    "CachedSemanticProbe",
    "CachedStructuralProbe",
    "cached",
]

#: Bumped whenever the key recipe or the file contents change, so old files miss.
CACHE_FORMAT = 1

_KINDS = {"semantic": SemanticPrediction, "masks": MaskSet}


def _jsonable(obj):
    """Plain JSON types from tuples, paths and numpy scalars/arrays."""
    if isinstance(obj, Mapping):
        out = {}
        for k, v in obj.items():
            if not isinstance(k, str):
                raise TypeError(f"configuration keys must be strings, got {k!r}")
            out[k] = _jsonable(v)
        return out
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if obj is None or isinstance(obj, (str, bool, int, float)):
        return obj
    raise TypeError(f"configuration value {obj!r} of type {type(obj).__name__} is not JSON-able")


def canonical_json(obj) -> str:
    """Deterministic JSON text: sorted keys, no whitespace, no NaN/Infinity.

    Tuples become lists, paths strings and numpy values Python values, so
    equal configurations give equal text.  Raises TypeError / ValueError on
    values JSON cannot represent exactly.
    """
    return json.dumps(_jsonable(obj), sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def image_digest(image: np.ndarray) -> str:
    """Hex SHA-256 of an image's content: dtype, shape and C-order bytes."""
    image = np.ascontiguousarray(image)
    digest = hashlib.sha256()
    digest.update(f"{image.dtype.str}|{image.shape}|".encode())
    digest.update(image.data)
    return digest.hexdigest()


def cache_key(image: np.ndarray, probe_name: str, config: Mapping, prompt: str | None = None) -> str:
    """Hex SHA-256 cache key of (image content, probe name, configuration, prompt).

    image: the view's RGB array; config: the probe's ``describe()``; prompt:
    the category prompt for semantic probes, None for structural ones.
    """
    payload = {
        "format": CACHE_FORMAT,
        "code": code_id.code_digest(),  # the probe's code, not only its configuration, makes its output
        "image": image_digest(image),
        "probe": probe_name,
        "config": config,
        "prompt": prompt,
    }
    return hashlib.sha256(canonical_json(payload).encode("utf-8")).hexdigest()


def _safe_dirname(name: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._")
    return cleaned or "probe"


class ProbeCache:
    """Directory of cached probe outputs (see module docstring).

    Counters ``hits``, ``misses`` and ``corrupt`` (entries that exist but
    cannot be read or decoded, also counted as misses) accumulate over the
    cache object's life.
    """

    def __init__(self, root: str | os.PathLike):
        self.root = Path(root)
        self.hits = 0
        self.misses = 0
        self.corrupt = 0

    def path_for(self, probe_name: str, key: str) -> Path:
        """Where the entry for ``key`` of probe ``probe_name`` lives."""
        return self.root / _safe_dirname(probe_name) / key[:2] / f"{key}.npz"

    def store(self, probe_name: str, key: str, result: SemanticPrediction | MaskSet) -> Path:
        """Write ``result`` under ``key`` (atomically); returns the file path."""
        if isinstance(result, SemanticPrediction):
            kind, scores, labels = "semantic", result.scores, result.labels
        elif isinstance(result, MaskSet):
            kind, scores, labels = "masks", result.scores, None
        else:
            raise TypeError(f"cannot cache a {type(result).__name__}")
        arrays = {
            "format": np.array(CACHE_FORMAT, np.int64),
            "key": np.array(key),
            "kind": np.array(kind),
            "probe": np.array(result.probe),
            "shape": np.array(result.masks.shape, np.int64),
            "bits": np.packbits(result.masks.reshape(-1)),
            "has_scores": np.array(scores is not None),
            "scores": np.zeros(0, np.float32) if scores is None else scores.astype(np.float32),
        }
        if labels is not None:
            arrays["labels"] = np.array(labels, dtype=np.str_).reshape(len(labels))
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        path = self.path_for(probe_name, key)
        write_bytes(path, buf.getvalue(), sync=False)  # an undecodable entry is a miss
        return path

    def load(self, probe_name: str, key: str, kind: str) -> SemanticPrediction | MaskSet | None:
        """The cached result for ``key``, or None on a miss.

        kind: "semantic" (-> SemanticPrediction) or "masks" (-> MaskSet).
        A corrupted or inconsistent file is a miss with an R360Warning.
        """
        if kind not in _KINDS:
            raise ValueError(f"kind must be one of {sorted(_KINDS)}, got {kind!r}")
        path = self.path_for(probe_name, key)
        try:
            data = path.read_bytes()
        except (FileNotFoundError, NotADirectoryError):
            self.misses += 1
            return None
        except OSError as exc:
            return self._bad_entry(path, f"unreadable probe cache file ({exc.strerror or exc})")
        try:
            result = self._parse(data, key, kind)
        except Exception as exc:  # noqa: BLE001 - any undecodable entry is just a miss
            return self._bad_entry(path, f"corrupted probe cache file ({type(exc).__name__}: {exc})")
        self.hits += 1
        return result

    def _bad_entry(self, path: Path, what: str) -> None:
        self.corrupt += 1
        self.misses += 1
        warnings.warn(f"{path}: {what}; recomputing", R360Warning, stacklevel=3)
        return None

    @staticmethod
    def _parse(data: bytes, key: str, kind: str) -> SemanticPrediction | MaskSet:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            if int(npz["format"]) != CACHE_FORMAT:
                raise ValueError(f"format {int(npz['format'])}, expected {CACHE_FORMAT}")
            if str(npz["key"]) != key:
                raise ValueError("stored key does not match the file name")
            if str(npz["kind"]) != kind:
                raise ValueError(f"holds a {str(npz['kind'])!r} result, expected {kind!r}")
            shape = tuple(int(s) for s in npz["shape"])
            if len(shape) != 3 or min(shape) < 0:
                raise ValueError(f"bad mask shape {shape}")
            n = math.prod(shape)
            bits = npz["bits"]
            if bits.dtype != np.uint8 or bits.shape != ((n + 7) // 8,):
                raise ValueError(f"mask bits of shape {bits.shape} do not fit masks of shape {shape}")
            masks = np.unpackbits(bits, count=n).astype(bool).reshape(shape)
            scores = npz["scores"] if bool(npz["has_scores"]) else None
            probe = str(npz["probe"])
            if kind == "semantic":
                labels = [str(s) for s in npz["labels"]]
                return SemanticPrediction(masks, scores, labels, probe)
            return MaskSet(masks, scores, probe)


def _predict_cached(
    probe: Probe,
    cache: ProbeCache,
    views: Sequence[ProbeView],
    prompt: str | None,
    kind: str,
    run: Callable[[list[ProbeView]], list],
) -> list:
    """Serve views from the cache; run the probe once on all the misses.

    A cache that cannot be written gives one warning per batch, never an error.
    """
    name = probe.name
    config = probe.describe()
    keys: list[str] = []
    results: list = [None] * len(views)
    todo: list[int] = []
    for i, view in enumerate(views):
        if view.image is None:
            raise InputError(f"probe {name!r} needs the rendered image of view {view.name!r}, and none was given")
        key = cache_key(view.image, name, config, prompt)
        keys.append(key)
        hit = cache.load(name, key, kind)
        if hit is None:
            todo.append(i)
        else:
            results[i] = hit
    if todo:
        batch = [views[i] for i in todo]
        fresh = run(batch)
        check_results(batch, fresh, name)
        unwritable = None
        for i, result in zip(todo, fresh):
            results[i] = result
            if unwritable is None:
                try:
                    cache.store(name, keys[i], result)
                except OSError as exc:
                    # The results are right; only re-use is lost, so say so and go on.
                    unwritable = exc
                    warnings.warn(
                        f"{cache.root}: cannot write the probe cache ({exc.strerror or exc}); results of probe "
                        f"{name!r} are not cached",
                        R360Warning,
                        stacklevel=3,
                    )
    return results


class _Wrapped:
    """Name, parameters, model hashes and ``describe()`` are the wrapped probe's."""

    def __init__(self, probe, cache: ProbeCache):
        self.probe = probe
        self.cache = cache

    @property
    def name(self) -> str:
        return self.probe.name

    def params(self) -> dict:
        return self.probe.params()

    def model_hashes(self) -> dict[str, str]:
        return self.probe.model_hashes()

    def describe(self) -> dict:
        return self.probe.describe()


class CachedSemanticProbe(_Wrapped, SemanticProbe):
    """A semantic probe whose per-view outputs go through a :class:`ProbeCache`."""

    def predict(self, views: Sequence[ProbeView], prompt: str) -> list[SemanticPrediction]:
        """Cached results where present; the wrapped probe runs on the rest (one batch)."""
        return _predict_cached(self.probe, self.cache, views, prompt, "semantic", lambda b: self.probe.predict(b, prompt))


class CachedStructuralProbe(_Wrapped, StructuralProbe):
    """A structural probe whose per-view outputs go through a :class:`ProbeCache`."""

    def predict(self, views: Sequence[ProbeView]) -> list[MaskSet]:
        """Cached results where present; the wrapped probe runs on the rest (one batch)."""
        return _predict_cached(self.probe, self.cache, views, None, "masks", self.probe.predict)


def cached(probe: Probe, cache: ProbeCache | None) -> Probe:
    """``probe`` wrapped in ``cache``; unchanged when there is no cache or the
    probe is not cacheable (precomputed masks are read from their files)."""
    if cache is None or not probe.cacheable or isinstance(probe, (CachedSemanticProbe, CachedStructuralProbe)):
        return probe
    if isinstance(probe, SemanticProbe):
        return CachedSemanticProbe(probe, cache)
    if isinstance(probe, StructuralProbe):
        return CachedStructuralProbe(probe, cache)
    raise TypeError(f"cannot cache a {type(probe).__name__}")
