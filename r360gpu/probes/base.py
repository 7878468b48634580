"""Probe interfaces and their result types.

Two kinds of probe exist (paper Sec. 3):

* a *semantic* probe maps (RGB rendering, category prompt) to instance masks
  with scores (`SemanticPrediction`); the semantic axis uses the union
  of the instances;
* a *structural* probe maps an RGB rendering to an unordered set of masks
  (`MaskSet`), e.g. SAM automatic masks.

Probes are batched over views (`ProbeView`).  A view is identified by
its name (the image file stem, shared by the pre / post / ref renderings of
one pose) and says which rendering it is, so that probes reading precomputed
masks can find the right file; model probes only look at the pixels.

Every probe reports ``describe()``: its name, kind, model file hashes and
parameters.  That dictionary goes into the results and, as the probe's full
configuration, into the on-disk cache key (`r360gpu.probes.cache`).

Several probes may serve one axis; every result records the name of the probe
that produced it (``probe``) so later stages can combine or compare them.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RENDERINGS",
    "ProbeView",
    "SemanticPrediction",
    "MaskSet",
    "Probe",
    "SemanticProbe",
    "StructuralProbe",
    "check_results",
]

#: Names of the three renderings of a pose (docs/protocol.md: I_pre, I_post, I_ref).
RENDERINGS = ("pre", "post", "ref")


def _as_mask_stack(masks, what: str) -> np.ndarray:
    """bool (K, H, W) from a bool or integer (K, H, W) array (non-zero = set)."""
    arr = np.asarray(masks)
    if arr.ndim != 3:
        raise ValueError(f"{what} must be (K, H, W), got shape {arr.shape}")
    if arr.dtype != bool:
        if not np.issubdtype(arr.dtype, np.integer):
            # Float masks are usually logits or probabilities: thresholding
            # them is the probe's decision, not something to do silently here.
            raise TypeError(f"{what} must be bool or integer, got {arr.dtype}")
        arr = arr != 0
    return arr


def _as_scores(scores, k: int, what: str) -> np.ndarray:
    if scores is None:
        raise ValueError(f"{what} must be float (K,) with K={k}, got None")
    arr = np.asarray(scores, dtype=np.float32)
    if arr.shape != (k,):
        raise ValueError(f"{what} must be float (K,) with K={k}, got shape {arr.shape}")
    return arr


@dataclass(frozen=True, eq=False)
class ProbeView:
    """One view handed to a probe.

    name: view identifier, the image file stem (e.g. ``"00012"``).
    image: RGB rendering, (H, W, 3), uint8 0..255 or float 0..1; None when only
        precomputed masks are used and no rendering is at hand.
    rendering: which rendering this is, one of `RENDERINGS`, or None
        when unknown (then precomputed probes cannot be used).
    size: (H, W) in pixels; taken from ``image`` when omitted.  Imported masks
        of another size are resized to it.
    method: for a "post" rendering, the name of the method whose edit it is
        (precomputed probes then prefer masks imported for that method).
    """

    name: str
    image: np.ndarray | None = None
    rendering: str | None = None
    size: tuple[int, int] | None = None
    method: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"view name must be a non-empty string, got {self.name!r}")
        if self.rendering is not None and self.rendering not in RENDERINGS:
            raise ValueError(f"rendering must be one of {RENDERINGS} or None, got {self.rendering!r}")
        size = None if self.size is None else (int(self.size[0]), int(self.size[1]))
        if self.image is not None:
            image = np.asarray(self.image)
            if image.ndim != 3 or image.shape[2] != 3:
                raise ValueError(f"view {self.name!r}: image must be (H, W, 3) RGB, got shape {image.shape}")
            if size is not None and size != image.shape[:2]:
                raise ValueError(f"view {self.name!r}: size {size} disagrees with image shape {image.shape[:2]}")
            size = (int(image.shape[0]), int(image.shape[1]))
            object.__setattr__(self, "image", image)
        if size is None:
            raise ValueError(f"view {self.name!r}: give an image or a size")
        if size[0] < 1 or size[1] < 1:
            raise ValueError(f"view {self.name!r}: size must be positive, got {size}")
        object.__setattr__(self, "size", size)

    @property
    def height(self) -> int:
        return self.size[0]

    @property
    def width(self) -> int:
        return self.size[1]


@dataclass(frozen=True, eq=False)
class SemanticPrediction:
    """Instances of the prompted category found in one view.

    masks: bool (K, H, W), one mask per retained instance (K may be 0).
    scores: float32 (K,), detection confidences; NaN where the source gave none.
    labels: K strings, the class name of each instance as the probe reported it.
    probe: name of the probe that produced this prediction.
    """

    masks: np.ndarray
    scores: np.ndarray
    labels: list[str]
    probe: str = ""

    def __post_init__(self) -> None:
        masks = _as_mask_stack(self.masks, "SemanticPrediction.masks")
        k = masks.shape[0]
        object.__setattr__(self, "masks", masks)
        object.__setattr__(self, "scores", _as_scores(self.scores, k, "SemanticPrediction.scores"))
        labels = [str(s) for s in self.labels]
        if len(labels) != k:
            raise ValueError(f"SemanticPrediction.labels must have K={k} entries, got {len(labels)}")
        object.__setattr__(self, "labels", labels)

    @classmethod
    def empty(cls, height: int, width: int, probe: str = "") -> "SemanticPrediction":
        """No detection: K = 0 instances on a (height, width) view."""
        return cls(np.zeros((0, height, width), bool), np.zeros(0, np.float32), [], probe)

    @property
    def count(self) -> int:
        """K, the number of instances."""
        return int(self.masks.shape[0])

    @property
    def size(self) -> tuple[int, int]:
        """(H, W) in pixels."""
        return int(self.masks.shape[1]), int(self.masks.shape[2])

    def union(self) -> np.ndarray:
        """bool (H, W): pixels covered by any instance (all False when K = 0)."""
        return self.masks.any(axis=0)


@dataclass(frozen=True, eq=False)
class MaskSet:
    """An unordered set of masks from a structural probe on one view.

    masks: bool (K, H, W) (K may be 0).
    scores: float32 (K,) quality scores (e.g. SAM's predicted IoU), or None.
    probe: name of the probe that produced this set.
    """

    masks: np.ndarray
    scores: np.ndarray | None = None
    probe: str = ""

    def __post_init__(self) -> None:
        masks = _as_mask_stack(self.masks, "MaskSet.masks")
        object.__setattr__(self, "masks", masks)
        if self.scores is not None:
            object.__setattr__(self, "scores", _as_scores(self.scores, masks.shape[0], "MaskSet.scores"))

    @classmethod
    def empty(cls, height: int, width: int, probe: str = "") -> "MaskSet":
        """The empty set of masks on a (height, width) view."""
        return cls(np.zeros((0, height, width), bool), None, probe)

    @property
    def count(self) -> int:
        """K, the number of masks."""
        return int(self.masks.shape[0])

    @property
    def size(self) -> tuple[int, int]:
        """(H, W) in pixels."""
        return int(self.masks.shape[1]), int(self.masks.shape[2])


class Probe(ABC):
    """Common part of every probe.

    Subclasses set ``kind`` and implement :meth:`name`, :meth:`params`,
    :meth:`model_hashes` (default: none) and their ``predict``; probes that
    learn from the scene set ``learns_from_scene`` and override :meth:`fit`.  ``cacheable``
    is False for probes whose output does not follow from the image pixels
    alone (precomputed masks read from files); the cache passes them through.
    """

    kind: str = ""
    cacheable: bool = True
    #: True for probes that learn from the scene (:meth:`fit` must run on the
    #: pre renderings before :meth:`predict`); scoring fits exactly these.
    learns_from_scene: bool = False

    def fit(self, images: Sequence, masks: Sequence) -> "Probe":
        """Learn from the scene: pre renderings (H, W, 3) and their target
        masks (H, W).  A no-op for probes that do not learn (the default);
        returns self."""
        return self

    @property
    @abstractmethod
    def name(self) -> str:
        """Short probe name recorded in every result, e.g. ``"gsam2"``."""

    @abstractmethod
    def params(self) -> dict:
        """Every parameter that changes the output, as JSON-able values."""

    def model_hashes(self) -> dict[str, str]:
        """Model file name -> hex SHA-256.  Implementations should compute the
        hashes once and memoise them: ``describe()`` is called per batch."""
        return {}

    def input_stamps(self, name: str, rendering: str | None, method: str | None = None) -> dict:
        """{path: :func:`~r360gpu.util.filehash.input_stamp`} of the per-view files :meth:`predict`
        reads for view ``name`` of ``rendering`` (precomputed masks), taken before it reads them:
        the view cache keeps a view's result only while those files are unchanged.  Probes whose
        output follows from the image and :meth:`describe` alone (models, built-in probes) read
        none: {}."""
        return {}

    def describe(self) -> dict:
        """{"name", "kind", "models": {file: sha256}, "params": {...}}.

        This is the probe's full configuration: it goes into the results and
        into the cache key.
        """
        return {
            "name": self.name,
            "kind": self.kind,
            "models": dict(self.model_hashes()),
            "params": self.params(),
        }


class SemanticProbe(Probe):
    """(RGB rendering, category prompt) -> :class:`SemanticPrediction` per view."""

    kind = "semantic"

    @abstractmethod
    def predict(self, views: Sequence[ProbeView], prompt: str) -> list[SemanticPrediction]:
        """One prediction per view, in order, each of the view's size."""


class StructuralProbe(Probe):
    """RGB rendering -> :class:`MaskSet` per view (prompt-free)."""

    kind = "structural"

    @abstractmethod
    def predict(self, views: Sequence[ProbeView]) -> list[MaskSet]:
        """One mask set per view, in order, each of the view's size."""


def check_results(views: Sequence[ProbeView], results: Sequence, probe: str) -> None:
    """Assert a probe returned one result of the right size per view.

    A mismatch is a bug in the probe, not bad user input: RuntimeError.
    """
    if len(results) != len(views):
        raise RuntimeError(f"probe {probe!r} returned {len(results)} results for {len(views)} views")
    for view, result in zip(views, results):
        if result.size != view.size:
            raise RuntimeError(
                f"probe {probe!r} returned a {result.size} result for view {view.name!r} of size {view.size}"
            )
