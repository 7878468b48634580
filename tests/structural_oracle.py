"""Plain reference of the hierarchy structural probe's masks, the algorithm as first written: every level
as a full label image, areas and first pixels from ``np.unique`` over every pixel of each level, and the
masks by :func:`label_masks_oracle` per level.  :mod:`r360gpu.probes.builtin_structural` computes the
same sets at the finest partition's granularity; ``tests/test_probes_structural_oracle.py`` holds them equal.
"""
from __future__ import annotations

import heapq

import cv2
import numpy as np

from r360gpu.probes.builtin import upsample_rows_cols
from r360gpu.probes.builtin_structural import StructuralParams, _boundaries, _graph_labels, edge_strength


def compact_oracle(labels: np.ndarray) -> np.ndarray:
    """Labels renumbered 0..n-1 in raster order of first occurrence, int32."""
    flat = labels.reshape(-1)
    _, first, inverse = np.unique(flat, return_index=True, return_inverse=True)
    rank = np.empty(first.shape[0], np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.shape[0])
    return rank[inverse].reshape(labels.shape).astype(np.int32)


def label_masks_oracle(labels: np.ndarray, ids, size) -> np.ndarray:
    """bool (K, H, W): mask k is the nearest-neighbour upsampled ``labels == ids[k]``, one mask at a time."""
    rows, cols = upsample_rows_cols(labels.shape, size)
    full = labels[rows[:, None], cols[None, :]]
    return np.stack([full == i for i in np.asarray(ids, np.int64)]) if len(ids) else np.zeros((0, *size), bool)


def hierarchy_levels_oracle(work: np.ndarray, params: StructuralParams) -> list[np.ndarray]:
    """One int64 (h, w) label image per level (region id: root * (n + 1) + the root's merge count)."""
    fine = StructuralParams(method="graph", sigma=params.sigma, k=params.fine_k, min_area_frac=params.fine_min_area_frac)
    labels = compact_oracle(_graph_labels(work, fine))
    n = int(labels.max()) + 1
    lab = cv2.cvtColor(work.astype(np.float32) / np.float32(255.0), cv2.COLOR_RGB2Lab).reshape(-1, 3)
    flat = labels.reshape(-1)
    count = np.bincount(flat, minlength=n).astype(np.float64).tolist()
    sums = np.stack([np.bincount(flat, weights=lab[:, c].astype(np.float64), minlength=n) for c in range(3)],
                    axis=1).tolist()
    weight = float(params.colour_weight)
    boundary: list[dict[int, list[float]]] = [dict() for _ in range(n)]
    for a, b, total, length in zip(*_boundaries(labels, edge_strength(work, float(params.edge_blur)))):
        boundary[a][b] = boundary[b][a] = [total, length]

    def cost(a: int, b: int) -> float:
        total, length = boundary[a][b]
        ca, cb = count[a], count[b]
        delta_e = sum((sums[a][c] / ca - sums[b][c] / cb) ** 2 for c in range(3)) ** 0.5
        return max(total / length, weight * delta_e)

    heap = [(cost(a, b), a, b, 0, 0) for a in range(n) for b in boundary[a] if a < b]
    heapq.heapify(heap)
    version = [0] * n
    alive = [True] * n
    parent = np.arange(n, dtype=np.int64)
    out = []
    for threshold in params.levels:
        while heap and heap[0][0] < threshold:
            _, a, b, va, vb = heapq.heappop(heap)
            if not (alive[a] and alive[b]) or version[a] != va or version[b] != vb:
                continue
            keep, gone = a, b
            alive[gone] = False
            parent[gone] = keep
            count[keep] += count[gone]
            sums[keep] = [sums[keep][c] + sums[gone][c] for c in range(3)]
            version[keep] += 1
            for other, edge in boundary[gone].items():
                if other == keep:
                    continue
                del boundary[other][gone]
                if other in boundary[keep]:
                    both = boundary[keep][other]
                    both[0] += edge[0]
                    both[1] += edge[1]
                else:
                    boundary[keep][other] = boundary[other][keep] = edge
            boundary[keep].pop(gone, None)
            boundary[gone] = {}
            for other in sorted(boundary[keep]):
                lo, hi = (keep, other) if keep < other else (other, keep)
                heapq.heappush(heap, (cost(lo, hi), lo, hi, version[lo], version[hi]))
        root = parent.copy()
        while True:
            nxt = root[root]
            if np.array_equal(nxt, root):
                break
            root = nxt
        ids = root * (n + 1) + np.asarray(version, np.int64)[root]
        out.append(ids[labels])
    return out


def hierarchy_masks_oracle(work: np.ndarray, params: StructuralParams, size) -> np.ndarray:
    """bool (K, H, W): the distinct regions of every level covering >= min_area_frac, largest first
    (ties: raster order of the first pixel), at most max_masks."""
    total = work.shape[0] * work.shape[1]
    seen: set[int] = set()
    found = []
    levels = hierarchy_levels_oracle(work, params)
    for level, ids in enumerate(levels):
        unique, first, counts = np.unique(ids.reshape(-1), return_index=True, return_counts=True)
        for u, f, c in zip(unique.tolist(), first.tolist(), counts.tolist()):
            if u in seen or c < params.min_area_frac * total:
                continue
            seen.add(u)
            found.append((-c, f, level, u))
    found.sort()
    found = found[: int(params.max_masks)]
    if not found:
        return np.zeros((0, size[0], size[1]), bool)
    return np.stack([label_masks_oracle(levels[level], [u], size)[0] for _, _, level, u in found])
