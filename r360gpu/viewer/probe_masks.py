"""Probe masks of a view, when ``r360gpu score`` cached them.

The probe cache (:mod:`r360gpu.probes.cache`) is keyed by the exact image a
probe saw, the probe's ``describe()`` and, for semantic probes, the prompt.
The viewer re-creates the image the evaluation gave the probes (the source's
``images(view, camera).rgb``: same renderer, same camera, same options) and
the probe descriptions listed in results.json, so a hit returns the masks
the scores were computed from (the key holds the code digest too: under other
r360gpu code every lookup misses); nothing is ever computed here.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from r360gpu.probes.cache import ProbeCache, cache_key


@dataclass(frozen=True)
class ProbeMasks:
    """Cached masks of one probe on one image: ``masks`` (K, H, W) bool; ``kind`` "semantic"/"structural"."""

    probe: str
    kind: str
    masks: np.ndarray


def cached_masks(cache_root: str | Path, probes: dict[str, list[dict]], image: np.ndarray,
                 prompt: str | None) -> list[ProbeMasks]:
    """Every probe of ``probes`` ({"semantic": [describe()...], "structural": [...]}) with a cache entry for ``image``."""
    root = Path(cache_root)
    if not root.is_dir():
        return []
    cache = ProbeCache(root)
    found = []
    for kind, stored in (("semantic", "semantic"), ("structural", "masks")):
        for desc in probes.get(kind, []):
            name = desc.get("name") if isinstance(desc, dict) else None
            if not name:
                continue
            key = cache_key(image, name, desc, prompt if kind == "semantic" else None)
            hit = cache.load(name, key, stored)
            if hit is not None:
                found.append(ProbeMasks(name, kind, np.asarray(hit.masks, bool)))
    return found


def instance_ids(masks: np.ndarray) -> np.ndarray:
    """(K, H, W) bool -> (H, W) uint32 instance id + 1 per pixel (later instances on top), 0 = none."""
    m = np.asarray(masks, bool)
    ids = np.zeros(m.shape[1:], np.uint32)
    for k in range(m.shape[0]):
        ids[m[k]] = k + 1
    return ids
