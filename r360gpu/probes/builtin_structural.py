"""Weight-free structural probe: classical over-segmentation as a stand-in for
SAM's automatic masks.

:class:`BuiltinStructuralProbe` returns, per view, an unordered set of
non-overlapping masks (a :class:`MaskSet`), like SAM's prompt-free masks, from
one of two classical segmenters in OpenCV contrib:

* ``"graph"`` (probe name ``builtin-graphseg``, the default) --
  Felzenszwalb-Huttenlocher graph-based segmentation
  (``cv2.ximgproc.segmentation.createGraphSegmentation(sigma, k, min_size)``)
  on the RGB working image;
* ``"slic"`` (probe name ``builtin-slic``) -- SLIC superpixels
  (``cv2.ximgproc.createSuperpixelSLIC``) on the Lab working image, followed
  by region merging (below), since superpixels alone are far smaller than
  objects.

Pipeline, per view:

1. The rendering is shrunk (area averaging) so its long side is at most
   ``work_long_side`` pixels; small images are used as they are.
2. The segmenter runs on that working image.  Its size parameters are scaled
   with the working image so that the number of segments depends little on
   the resolution: the minimum segment size is ``min_area_frac`` of the
   working area (at least 1 pixel); Felzenszwalb's ``k`` is multiplied by
   ``(working area / REFERENCE_AREA) ** K_AREA_EXPONENT``
   (``REFERENCE_AREA`` = 512 x 288, the working image of a 16:9 frame;
   exponent 1/4); ``sigma`` is in working-image pixels.  The exponent is
   empirical: ``k`` is a pixel-count scale, but a smaller image also has
   larger colour steps between neighbouring pixels, and with 1/4 the segment
   count of two test photographs stayed within about +-25% from 1920x1080
   down to 160x90 (plain area scaling tripled it at the small sizes).  SLIC's
   region size is ``slic_region_frac`` of the working long side.
3. Optional merging (``merge_delta_e`` > 0): adjacent segments whose mean
   colours differ by less than ``merge_delta_e`` (CIE76 Delta-E, CIELAB
   units) are merged greedily, closest pair first, with the mean colours
   updated after every merge.
4. Segments covering less than ``min_area_frac`` of the working image are
   dropped (their pixels belong to no mask, as with SAM); of the rest the
   ``max_masks`` largest are kept, ordered by area (ties: raster order of
   their first pixel).
5. Labels are brought back to the view's size by nearest neighbour, so mask
   boundaries are as coarse as the working image (about 4 px at 1920x1080
   with the default 512).

Masks have no quality scores (``MaskSet.scores`` is None).  An image of one
colour gives a single mask covering the whole image; in the structural axis
a mask is retained only when its IoU with the target mask M is >= 0.1, so
such a mask counts only where M covers at least 10% of the image.

Everything is deterministic (no random initialisation anywhere).

What it can and cannot see: it responds to colour/texture boundaries, not to
object semantics.  It over-segments textured or shaded objects (one object,
several masks) and under-segments objects whose colour matches their
surroundings (object and background in one mask); it cannot tell an object
from a stain of the same extent.  It is weaker than SAM and exists so that
the structural axis can be computed anywhere.
"""
from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import cv2
import numpy as np

from r360gpu.errors import InputError
from r360gpu.probes.base import MaskSet, ProbeView, StructuralProbe
from r360gpu.probes.builtin import as_rgb_uint8, label_masks, to_working, working_size

__all__ = [
    "REFERENCE_AREA",
    "K_AREA_EXPONENT",
    "STRUCTURAL_LIMITATIONS",
    "StructuralParams",
    "segment_labels",
    "BuiltinStructuralProbe",
]

#: Working-image area (pixels) at which ``k`` applies unscaled: 512 x 288,
#: the default working image of a 16:9 rendering.
REFERENCE_AREA = 512 * 288

#: ``k`` is scaled by (working area / REFERENCE_AREA) to this power (module docstring, step 2).
K_AREA_EXPONENT = 0.25

#: One-line limitation statement recorded in ``describe()``.
STRUCTURAL_LIMITATIONS = (
    "classical colour/texture segmentation, not SAM: responds to colour and texture boundaries, not to "
    "object semantics; over-segments textured objects and merges objects into same-coloured surroundings"
)

_METHODS = ("graph", "slic")


def _check(ok: bool, problem: str) -> None:
    if not ok:
        raise InputError(f"structural probe parameters: {problem}")


@dataclass(frozen=True)
class StructuralParams:
    """Parameters of :class:`BuiltinStructuralProbe` (all go into ``describe()``).

    method: ``"graph"`` (Felzenszwalb) or ``"slic"`` (superpixels + merging).
    work_long_side: long side (px) of the working image; larger renderings
        are shrunk to it, smaller ones are used as they are.
    sigma: Gaussian pre-smoothing (working-image px) of the graph segmenter.
    k: Felzenszwalb's scale at :data:`REFERENCE_AREA` (larger: larger
        segments); scaled by (working area / reference) ** K_AREA_EXPONENT.
    min_area_frac: smallest segment kept, as a fraction of the image area
        (also the graph segmenter's ``min_size``).
    slic_region_frac: SLIC superpixel size as a fraction of the working long side.
    slic_ruler: SLIC compactness (larger: more regular superpixels).
    slic_iterations: SLIC iterations.
    merge_delta_e: merge adjacent segments whose mean colours are closer than
        this (CIE76 Delta-E); 0 disables merging.
    max_masks: at most this many masks per view (the largest).
    """

    method: str = "graph"
    work_long_side: int = 512
    sigma: float = 0.8
    k: float = 1000.0
    min_area_frac: float = 0.002
    slic_region_frac: float = 0.04
    slic_ruler: float = 20.0
    slic_iterations: int = 10
    merge_delta_e: float = 0.0
    max_masks: int = 100

    def __post_init__(self) -> None:
        _check(self.method in _METHODS, f"method must be one of {_METHODS}, got {self.method!r}")
        _check(int(self.work_long_side) >= 8, f"work_long_side must be >= 8, got {self.work_long_side}")
        _check(float(self.sigma) >= 0, f"sigma must be >= 0, got {self.sigma}")
        _check(float(self.k) > 0, f"k must be > 0, got {self.k}")
        _check(0 <= float(self.min_area_frac) < 1, f"min_area_frac must be in [0, 1), got {self.min_area_frac}")
        _check(0 < float(self.slic_region_frac) <= 1, f"slic_region_frac must be in (0, 1], got {self.slic_region_frac}")
        _check(float(self.slic_ruler) > 0, f"slic_ruler must be > 0, got {self.slic_ruler}")
        _check(int(self.slic_iterations) >= 1, f"slic_iterations must be >= 1, got {self.slic_iterations}")
        _check(float(self.merge_delta_e) >= 0, f"merge_delta_e must be >= 0, got {self.merge_delta_e}")
        _check(int(self.max_masks) >= 1, f"max_masks must be >= 1, got {self.max_masks}")

    @classmethod
    def slic(cls, **overrides) -> "StructuralParams":
        """The SLIC variant's defaults: superpixels merged below Delta-E 10."""
        values = {"method": "slic", "merge_delta_e": 10.0}
        values.update(overrides)
        return cls(**values)


def _graph_labels(work: np.ndarray, params: StructuralParams) -> np.ndarray:
    area = work.shape[0] * work.shape[1]
    min_size = max(1, int(round(params.min_area_frac * area)))
    k = float(params.k) * (area / REFERENCE_AREA) ** K_AREA_EXPONENT
    seg = cv2.ximgproc.segmentation.createGraphSegmentation(float(params.sigma), k, min_size)
    return seg.processImage(work)


def _slic_labels(work: np.ndarray, params: StructuralParams) -> np.ndarray:
    h, w = work.shape[:2]
    region = max(2, int(round(params.slic_region_frac * max(h, w))))
    if h < 2 or w < 2 or region > max(h, w):
        # Too small for one superpixel grid cell: the whole image is one region.
        return np.zeros((h, w), np.int32)
    lab = cv2.cvtColor(work, cv2.COLOR_RGB2Lab)
    slic = cv2.ximgproc.createSuperpixelSLIC(lab, cv2.ximgproc.SLIC, region, float(params.slic_ruler))
    slic.iterate(int(params.slic_iterations))
    slic.enforceLabelConnectivity(25)
    return slic.getLabels()


def _compact(labels: np.ndarray) -> np.ndarray:
    """Labels renumbered 0..n-1 in raster order of first occurrence, int32."""
    flat = labels.reshape(-1)
    _, first, inverse = np.unique(flat, return_index=True, return_inverse=True)
    rank = np.empty(first.shape[0], np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.shape[0])
    return rank[inverse].reshape(labels.shape).astype(np.int32)


def _adjacent_pairs(labels: np.ndarray) -> np.ndarray:
    """int64 (P, 2) distinct label pairs (a < b) that touch (4-neighbourhood)."""
    pairs = []
    for a, b in ((labels[:, :-1], labels[:, 1:]), (labels[:-1, :], labels[1:, :])):
        differ = a != b
        lo = np.minimum(a[differ], b[differ]).astype(np.int64)
        hi = np.maximum(a[differ], b[differ]).astype(np.int64)
        pairs.append(np.stack([lo, hi], axis=1))
    both = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
    return np.unique(both, axis=0) if both.size else both


def _merge_similar(labels: np.ndarray, work: np.ndarray, delta_e: float) -> np.ndarray:
    """Greedy region merging: repeatedly merge the adjacent pair of segments
    with the closest mean CIELAB colours while that distance is < delta_e.

    labels: int (h, w) compact labels 0..n-1; work: uint8 (h, w, 3) RGB.
    Returns int32 (h, w) labels (not compacted).
    """
    n = int(labels.max()) + 1
    pairs = _adjacent_pairs(labels)
    if n < 2 or pairs.shape[0] == 0:
        return labels
    lab = cv2.cvtColor(work.astype(np.float32) / np.float32(255.0), cv2.COLOR_RGB2Lab).reshape(-1, 3)
    flat = labels.reshape(-1)
    count = np.bincount(flat, minlength=n).astype(np.float64)
    sums = np.stack([np.bincount(flat, weights=lab[:, c].astype(np.float64), minlength=n) for c in range(3)], axis=1)
    count_l = count.tolist()
    sums_l = sums.tolist()
    neighbours: list[set[int]] = [set() for _ in range(n)]
    for a, b in pairs.tolist():
        neighbours[a].add(b)
        neighbours[b].add(a)
    version = [0] * n
    alive = [True] * n
    parent = list(range(n))

    def distance(a: int, b: int) -> float:
        ca, cb = count_l[a], count_l[b]
        sa, sb = sums_l[a], sums_l[b]
        return float(np.sqrt(sum((sa[c] / ca - sb[c] / cb) ** 2 for c in range(3))))

    heap = [(distance(a, b), a, b, 0, 0) for a, b in pairs.tolist()]
    heapq.heapify(heap)
    while heap:
        d, a, b, va, vb = heapq.heappop(heap)
        if d >= delta_e:
            break
        if not (alive[a] and alive[b]) or version[a] != va or version[b] != vb:
            continue  # stale: one side was merged or changed since this entry was pushed
        # Keep the smaller id as the survivor so the result does not depend on pair order.
        keep, gone = (a, b) if a < b else (b, a)
        alive[gone] = False
        parent[gone] = keep
        count_l[keep] += count_l[gone]
        sums_l[keep] = [sums_l[keep][c] + sums_l[gone][c] for c in range(3)]
        version[keep] += 1
        merged = (neighbours[keep] | neighbours[gone]) - {keep, gone}
        for other in neighbours[gone]:
            neighbours[other].discard(gone)
        neighbours[gone] = set()
        neighbours[keep] = merged
        for other in sorted(merged):
            neighbours[other].add(keep)
            lo, hi = (keep, other) if keep < other else (other, keep)
            heapq.heappush(heap, (distance(lo, hi), lo, hi, version[lo], version[hi]))
    root = np.arange(n, dtype=np.int64)
    for i in range(n):
        j = i
        while parent[j] != j:
            j = parent[j]
        root[i] = j
    return root[labels].astype(np.int32)


def segment_labels(rgb: np.ndarray, params: StructuralParams) -> np.ndarray:
    """Segment label image of a uint8 RGB working image (steps 2-3 of the module docstring).

    Returns int32 (h, w) labels 0..n-1, numbered in raster order of first occurrence.
    """
    labels = _graph_labels(rgb, params) if params.method == "graph" else _slic_labels(rgb, params)
    labels = _compact(labels)
    if params.merge_delta_e > 0:
        labels = _compact(_merge_similar(labels, rgb, float(params.merge_delta_e)))
    return labels


def _select(labels: np.ndarray, params: StructuralParams) -> np.ndarray:
    """Label ids kept by step 4 (size filter, largest ``max_masks``), in output order."""
    area = np.bincount(labels.reshape(-1))
    total = labels.size
    ids = np.flatnonzero((area > 0) & (area >= params.min_area_frac * total))
    # Compact labels are numbered in raster order of first pixel, so the id
    # itself breaks area ties the documented way.
    order = np.lexsort((ids, -area[ids]))
    return ids[order][: int(params.max_masks)]


class BuiltinStructuralProbe(StructuralProbe):
    """Weight-free prompt-free mask sets from classical segmentation (module docstring).

    params: :class:`StructuralParams` (default: graph-based segmentation).
    """

    def __init__(self, params: StructuralParams | None = None):
        self.config = StructuralParams() if params is None else params

    @property
    def name(self) -> str:
        return "builtin-graphseg" if self.config.method == "graph" else "builtin-slic"

    def params(self) -> dict:
        values = asdict(self.config)
        values["reference_area"] = REFERENCE_AREA
        values["k_area_exponent"] = K_AREA_EXPONENT
        return values

    def describe(self) -> dict:
        """Base description plus ``weight_free: True`` and a one-line ``limitations``."""
        out = super().describe()
        out["weight_free"] = True
        out["limitations"] = STRUCTURAL_LIMITATIONS
        return out

    def predict_image(self, image: np.ndarray, what: str = "image") -> MaskSet:
        """Mask set of one RGB image ((H, W, 3) uint8 or float 0..1): bool (K, H, W), scores None."""
        rgb = as_rgb_uint8(image, what)
        size = rgb.shape[:2]
        work = to_working(rgb, working_size(size[0], size[1], int(self.config.work_long_side)))
        labels = segment_labels(work, self.config)
        ids = _select(labels, self.config)
        return MaskSet(label_masks(labels, ids, size), None, self.name)

    def predict(self, views: Sequence[ProbeView]) -> list[MaskSet]:
        """One MaskSet per view, at the view's size; every view needs its image."""
        out = []
        for view in views:
            if view.image is None:
                raise InputError(f"probe {self.name!r} needs the rendered image of view {view.name!r}, and none was given")
            out.append(self.predict_image(view.image, f"view {view.name!r}"))
        return out
