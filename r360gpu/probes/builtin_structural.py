"""Weight-free structural probe: classical segmentation as a stand-in for
SAM's automatic masks.

:class:`BuiltinStructuralProbe` returns, per view, an unordered set of masks
(a :class:`MaskSet`), like SAM's prompt-free masks.  The default,
``"hierarchy"`` (probe name ``builtin-hierarchy``), gives masks at several
granularities, as SAM's automatic masks come as whole, part and sub-part:

* the finest partition is Felzenszwalb's graph segmentation with a small
  ``fine_k`` (many small regions that follow colour edges);
* adjacent regions are merged greedily, cheapest first; the cost of a pair is
  ``max(mean edge strength along their shared boundary, colour_weight *
  Delta-E of their mean colours)``, where the edge strength is the Sobel
  gradient magnitude of the blurred CIELAB image (:func:`edge_strength`).
  Edge-aware: one weak spot in an occlusion boundary does not join an object
  to its surroundings (Felzenszwalb's single-linkage criterion does), while
  texture inside a region is weak on average;
* a partition is taken where the cheapest remaining merge reaches each of
  ``levels`` (2, 4, 8): sub-parts, parts, wholes.  Every distinct region of
  any level covering at least ``min_area_frac`` of the image is a mask; a
  region unchanged between levels is one mask, so masks are nested or
  disjoint, never repeated.  Largest first, at most ``max_masks``.

Why several levels: with one partition an object often ends up in one region
with its surroundings (the demo garden's bench with the brick wall behind it);
that region is nearly the same with and without the object, so the unedited
scene scored as a removal (the identity control) looked like a good removal.
``bench/structural_controls.py`` prints the controls: the levels and weights
were set on the demo room and checked on the demo garden and two PlayCanvas
splats (guitar, biker).

The one-level segmenters remain, with non-overlapping masks, from OpenCV
contrib:

* ``"graph"`` (probe name ``builtin-graphseg``) --
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

(Steps 2-5 describe the one-level methods; the hierarchy's working image,
sizes and upsampling are the same.)

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
from r360gpu.probes.builtin import as_rgb_uint8, label_masks, lut_masks, to_working, working_size

__all__ = [
    "REFERENCE_AREA",
    "K_AREA_EXPONENT",
    "STRUCTURAL_LIMITATIONS",
    "StructuralParams",
    "segment_labels",
    "edge_strength",
    "hierarchy_levels",
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

_METHODS = ("hierarchy", "graph", "slic")


def _check(ok: bool, problem: str) -> None:
    if not ok:
        raise InputError(f"structural probe parameters: {problem}")


@dataclass(frozen=True)
class StructuralParams:
    """Parameters of :class:`BuiltinStructuralProbe` (all go into ``describe()``).

    method: ``"hierarchy"`` (multi-level edge-aware merging, the default),
        ``"graph"`` (Felzenszwalb, one level) or ``"slic"`` (superpixels + merging).
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
    fine_k, fine_min_area_frac: Felzenszwalb's ``k`` (at :data:`REFERENCE_AREA`)
        and minimum segment size of the hierarchy's finest partition.
    levels: the hierarchy's merge thresholds (ascending); one partition is
        taken where the weakest remaining boundary reaches each.
    colour_weight: weight of the mean-colour difference (Delta-E) in the
        merge cost, next to the mean edge strength along the shared boundary.
    edge_blur: Gaussian blur (working-image px) before the edge strength.
    """

    method: str = "hierarchy"
    work_long_side: int = 512
    sigma: float = 0.8
    k: float = 1000.0
    min_area_frac: float = 0.002
    slic_region_frac: float = 0.04
    slic_ruler: float = 20.0
    slic_iterations: int = 10
    merge_delta_e: float = 0.0
    max_masks: int = 100
    fine_k: float = 50.0
    fine_min_area_frac: float = 0.0005
    levels: tuple = (2.0, 4.0, 8.0)
    colour_weight: float = 0.5
    edge_blur: float = 1.0

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
        _check(float(self.fine_k) > 0, f"fine_k must be > 0, got {self.fine_k}")
        _check(0 <= float(self.fine_min_area_frac) < 1,
               f"fine_min_area_frac must be in [0, 1), got {self.fine_min_area_frac}")
        levels = tuple(float(t) for t in self.levels)
        _check(len(levels) >= 1 and all(t > 0 for t in levels) and list(levels) == sorted(set(levels)),
               f"levels must be distinct positive thresholds in ascending order, got {self.levels}")
        object.__setattr__(self, "levels", levels)
        _check(float(self.colour_weight) >= 0, f"colour_weight must be >= 0, got {self.colour_weight}")
        _check(float(self.edge_blur) >= 0, f"edge_blur must be >= 0, got {self.edge_blur}")

    @classmethod
    def graph(cls, **overrides) -> "StructuralParams":
        """The one-level Felzenszwalb variant (the default before the hierarchy)."""
        return cls(**{"method": "graph", **overrides})

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


def _raster_firsts(flat: np.ndarray) -> np.ndarray | None:
    """First index of each label when ``flat`` is already numbered 0..n-1 in
    raster order of first occurrence (int64 (n,), increasing), else None.

    Such labels never go below 0 and rise by at most 1 over their running
    maximum, so every value up to the maximum has appeared; the graph
    segmenter numbers its regions that way, which spares a sort of every pixel.
    """
    if flat.size == 0 or flat[0] != 0 or flat.min() < 0:
        return None
    steps = np.diff(np.maximum.accumulate(flat))
    if steps.size and steps.max() > 1:
        return None
    return np.concatenate(([0], np.flatnonzero(steps) + 1)).astype(np.int64)


def _compact_firsts(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(labels renumbered 0..n-1 in raster order of first occurrence, int32;
    the first pixel (flat index) of each new label, int64 (n,), increasing)."""
    flat = labels.reshape(-1)
    firsts = _raster_firsts(flat)
    if firsts is not None:
        return labels.astype(np.int32), firsts
    _, first, inverse = np.unique(flat, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(first.shape[0], np.int64)
    rank[order] = np.arange(first.shape[0])
    return rank[inverse].reshape(labels.shape).astype(np.int32), first[order].astype(np.int64)


def _compact(labels: np.ndarray) -> np.ndarray:
    """Labels renumbered 0..n-1 in raster order of first occurrence, int32."""
    return _compact_firsts(labels)[0]


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
    lab = _working_lab(work).reshape(-1, 3)
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


def _working_lab(work: np.ndarray) -> np.ndarray:
    """float32 (h, w, 3) CIELAB of a uint8 RGB image (OpenCV's float conversion)."""
    return cv2.cvtColor(work.astype(np.float32) / np.float32(255.0), cv2.COLOR_RGB2Lab)


def edge_strength(work: np.ndarray, blur: float) -> np.ndarray:
    """float32 (h, w) colour edge strength of a uint8 RGB image: the Sobel
    gradient magnitude of the (blurred) CIELAB image, summed over the three
    channels in quadrature, in Delta-E per pixel (Sobel / 8)."""
    return _lab_edge_strength(_working_lab(work), blur)


def _lab_edge_strength(lab: np.ndarray, blur: float) -> np.ndarray:
    """:func:`edge_strength` of an image already converted by :func:`_working_lab`."""
    if blur > 0:
        lab = cv2.GaussianBlur(lab, (0, 0), float(blur))
    total = np.zeros(lab.shape[:2], np.float32)
    for c in range(3):
        gx = cv2.Sobel(lab[..., c], cv2.CV_32F, 1, 0, ksize=3) / np.float32(8.0)
        gy = cv2.Sobel(lab[..., c], cv2.CV_32F, 0, 1, ksize=3) / np.float32(8.0)
        total += gx * gx + gy * gy
    return np.sqrt(total)


def _boundaries(labels: np.ndarray, strength: np.ndarray) -> tuple[list, list, list, list]:
    """Touching label pairs (a < b, 4-neighbourhood) with the summed edge
    strength along their shared boundary (per neighbouring pixel pair, the
    stronger of the two pixels) and the boundary's length in pixel pairs."""
    n = int(labels.max()) + 1
    keys, values = [], []
    for a, b, sa, sb in ((labels[:, :-1], labels[:, 1:], strength[:, :-1], strength[:, 1:]),
                         (labels[:-1, :], labels[1:, :], strength[:-1, :], strength[1:, :])):
        differ = a != b
        lo = np.minimum(a[differ], b[differ]).astype(np.int64)
        hi = np.maximum(a[differ], b[differ]).astype(np.int64)
        keys.append(lo * n + hi)
        values.append(np.maximum(sa[differ], sb[differ]).astype(np.float64))
    key = np.concatenate(keys)
    if key.size == 0:
        return [], [], [], []
    unique, inverse = np.unique(key, return_inverse=True)
    sums = np.bincount(inverse, weights=np.concatenate(values))
    lengths = np.bincount(inverse).astype(np.float64)
    return (unique // n).tolist(), (unique % n).tolist(), sums.tolist(), lengths.tolist()


def hierarchy_levels(work: np.ndarray, params: StructuralParams) -> list[np.ndarray]:
    """The partitions of the segmentation hierarchy (module docstring, "hierarchy").

    work: uint8 (h, w, 3) RGB working image.  Returns one int64 (h, w) label
    image per threshold of ``params.levels`` (finest first); a region that no
    merge touched between two levels keeps its label, so equal labels across
    levels are the same region.
    """
    labels, _, tables = _hierarchy(work, params)
    return [table[labels] for table in tables]


def _hierarchy(work: np.ndarray, params: StructuralParams) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """The hierarchy as tables over its finest partition: (fine labels, int32
    (h, w), numbered in raster order of first pixel; each fine label's first
    pixel, int64 (n,), increasing; per level, int64 (n,): the region id of
    each fine label).  Every level is a union of fine regions, so the tables
    say everything about the levels without a pass over the pixels per level."""
    fine = StructuralParams(method="graph", sigma=params.sigma, k=params.fine_k, min_area_frac=params.fine_min_area_frac)
    labels, firsts = _compact_firsts(_graph_labels(work, fine))
    n = int(labels.max()) + 1
    lab_image = _working_lab(work)
    lab = lab_image.reshape(-1, 3)
    flat = labels.reshape(-1)
    count = np.bincount(flat, minlength=n).astype(np.float64)
    sums_array = np.stack([np.bincount(flat, weights=lab[:, c].astype(np.float64), minlength=n) for c in range(3)],
                          axis=1)
    # Mean colours kept per region (the same float divisions the cost would repeat on every call).
    means = (sums_array / count[:, None]).tolist()
    count, sums = count.tolist(), sums_array.tolist()
    weight = float(params.colour_weight)

    def cost(a: int, b: int, total: float, length: float) -> float:
        # Mean edge strength along the shared boundary, raised to the colour
        # difference of the two regions' means (weighted): texture edges inside
        # an object are weak on average and its parts have similar colours, while
        # an occlusion boundary is strong along most of its length or separates
        # different colours.  (Written out as sum() of the three squares added
        # them, left to right, so every cost is the same float.)
        ma, mb = means[a], means[b]
        delta_e = ((ma[0] - mb[0]) ** 2 + (ma[1] - mb[1]) ** 2 + (ma[2] - mb[2]) ** 2) ** 0.5
        return max(total / length, weight * delta_e)

    # boundary[a][b] = [summed edge strength, length]; one list shared by both directions.
    boundary: list[dict[int, list[float]]] = [dict() for _ in range(n)]
    heap = []
    for a, b, total, length in zip(*_boundaries(labels, _lab_edge_strength(lab_image, float(params.edge_blur)))):
        boundary[a][b] = boundary[b][a] = [total, length]
        heap.append((cost(a, b, total, length), a, b, 0, 0))
    # Entries are distinct tuples, so the order of pops is that of the sorted entries whatever the heap's layout.
    heapq.heapify(heap)
    version = [0] * n
    alive = [True] * n
    parent = np.arange(n, dtype=np.int64)
    tables = []
    for threshold in params.levels:
        while heap and heap[0][0] < threshold:
            _, a, b, va, vb = heapq.heappop(heap)
            if not (alive[a] and alive[b]) or version[a] != va or version[b] != vb:
                continue  # stale: one side was merged or changed since this entry was pushed
            keep, gone = a, b  # a < b: the smaller id survives, so the result does not depend on pair order
            alive[gone] = False
            parent[gone] = keep
            count[keep] += count[gone]
            sk, sg = sums[keep], sums[gone]
            sk = sums[keep] = [sk[0] + sg[0], sk[1] + sg[1], sk[2] + sg[2]]
            ck = count[keep]
            means[keep] = [sk[0] / ck, sk[1] / ck, sk[2] / ck]
            version[keep] += 1
            edges = boundary[keep]
            for other, edge in boundary[gone].items():
                if other == keep:
                    continue
                del boundary[other][gone]
                if other in edges:
                    both = edges[other]
                    both[0] += edge[0]
                    both[1] += edge[1]
                else:
                    edges[other] = boundary[other][keep] = edge
            edges.pop(gone, None)
            boundary[gone] = {}
            vk = version[keep]
            for other in sorted(edges):
                total, length = edges[other]
                if keep < other:
                    heapq.heappush(heap, (cost(keep, other, total, length), keep, other, vk, version[other]))
                else:
                    heapq.heappush(heap, (cost(other, keep, total, length), other, keep, version[other], vk))
        tables.append(_level_ids(parent, version))
    return labels, firsts, tables


def _level_ids(parent: np.ndarray, version: list[int]) -> np.ndarray:
    """int64 (n,): each fine label's region id at the current level: its root
    and that root's merge count, so a region unchanged since the previous level
    keeps its id."""
    root = parent.copy()
    while True:  # path halving over the whole array until every id points at its root
        nxt = root[root]
        if np.array_equal(nxt, root):
            break
        root = nxt
    return root * (parent.shape[0] + 1) + np.asarray(version, np.int64)[root]


def _hierarchy_masks(work: np.ndarray, params: StructuralParams, size: tuple[int, int]) -> np.ndarray:
    """bool (K, H, W): every distinct region of the hierarchy's levels covering at
    least ``min_area_frac`` of the image, largest first (ties: raster order of
    their first pixel), at most ``max_masks``; masks of different levels overlap.

    Areas and first pixels come from the fine regions (a region's area is the
    sum of its fine regions' areas, its first pixel that of its lowest fine
    label, fine labels being numbered in raster order); the masks from one
    table per level mapping each fine label to its mask (:func:`lut_masks`)."""
    labels, firsts, tables = _hierarchy(work, params)
    fine_area = np.bincount(labels.reshape(-1), minlength=firsts.shape[0]).astype(np.float64)
    total = labels.size
    seen: set[int] = set()
    found = []  # (-area, first pixel, level, id)
    regions = []  # per level: (region ids sorted, each fine label's index among them)
    for level, table in enumerate(tables):
        unique, lowest, inverse = np.unique(table, return_index=True, return_inverse=True)
        regions.append((unique, inverse))
        counts = np.bincount(inverse, weights=fine_area).astype(np.int64)  # sums of ints < 2**53: exact
        for u, f, c in zip(unique.tolist(), firsts[lowest].tolist(), counts.tolist()):
            if u in seen or c < params.min_area_frac * total:
                continue
            seen.add(u)
            found.append((-c, f, level, u))
    found.sort()
    found = found[: int(params.max_masks)]
    luts = []
    for level, (unique, inverse) in enumerate(regions):
        rows = [i for i, f in enumerate(found) if f[2] == level]
        if rows:
            slot = np.full(unique.shape[0], -1, np.int64)
            slot[np.searchsorted(unique, [found[i][3] for i in rows])] = rows
            luts.append(slot[inverse])
    return lut_masks(labels, luts, len(found), size)


def segment_labels(rgb: np.ndarray, params: StructuralParams) -> np.ndarray:
    """Segment label image of a uint8 RGB working image (steps 2-3 of the module docstring).

    Returns int32 (h, w) labels 0..n-1, numbered in raster order of first occurrence.
    """
    if params.method == "hierarchy":
        raise ValueError("segment_labels: the hierarchy has several partitions; use hierarchy_levels")
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

    params: `StructuralParams` (default: graph-based segmentation).
    """

    def __init__(self, params: StructuralParams | None = None):
        self.config = StructuralParams() if params is None else params

    @property
    def name(self) -> str:
        return {"hierarchy": "builtin-hierarchy", "graph": "builtin-graphseg", "slic": "builtin-slic"}[self.config.method]

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
        if self.config.method == "hierarchy":
            return MaskSet(_hierarchy_masks(work, self.config, size), None, self.name)
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
