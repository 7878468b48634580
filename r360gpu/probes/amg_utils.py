"""Pure-numpy pieces of SAM's automatic mask generator (AMG).

Re-implemented from the algorithm of segment-anything's
``automatic_mask_generator.py`` / ``utils/amg.py`` (and SAM2's, which is the
same) without torch, torchvision or RLE: masks stay boolean arrays.

Conventions:

* Points are (x, y) in pixels of the image (or crop) they were made for.
* Boxes are XYXY.  Mask boxes (:func:`masks_to_boxes`) are *inclusive*
  pixel indices ``[x_min, y_min, x_max, y_max]`` of the set pixels, as
  ``batched_mask_to_box``; an empty mask gives ``[0, 0, 0, 0]``.  Crop boxes
  are exclusive ``[x0, y0, x1, y1]`` (the crop is ``image[y0:y1, x0:x1]``).
* Box area and IoU follow torchvision: area ``(x1 - x0) * (y1 - y0)``
  (so a one-pixel mask box has area 0); IoU = intersection / union with a
  zero union giving IoU 0 (torchvision gives NaN, which never suppresses --
  the same outcome in :func:`nms`).
"""

from __future__ import annotations

import math
from itertools import product

import cv2
import numpy as np

__all__ = [
    "build_point_grid",
    "build_all_layer_point_grids",
    "generate_crop_boxes",
    "stability_score",
    "masks_to_boxes",
    "box_area",
    "box_iou",
    "nms",
    "is_box_near_crop_edge",
    "uncrop_boxes",
    "uncrop_points",
    "uncrop_masks",
    "remove_small_regions",
]


def build_point_grid(n_per_side: int) -> np.ndarray:
    """float64 (n*n, 2) points (x, y) in [0, 1]^2 at the centres of an n x n grid of cells.

    Row-major: x varies fastest.  Multiply by (width, height) for pixels.
    """
    n = int(n_per_side)
    if n < 1:
        raise ValueError(f"points per side must be >= 1, got {n_per_side}")
    offset = 1.0 / (2 * n)
    side = np.linspace(offset, 1.0 - offset, n)
    xs = np.tile(side[None, :], (n, 1))
    ys = np.tile(side[:, None], (1, n))
    return np.stack([xs, ys], axis=-1).reshape(-1, 2)


def build_all_layer_point_grids(n_per_side: int, n_layers: int, scale_per_layer: int) -> list[np.ndarray]:
    """Point grids for crop layers 0..n_layers: layer i has
    ``int(n_per_side / scale_per_layer**i)`` points per side."""
    return [build_point_grid(int(n_per_side / (scale_per_layer**i))) for i in range(n_layers + 1)]


def generate_crop_boxes(
    im_size: tuple[int, int], n_layers: int, overlap_ratio: float
) -> tuple[list[list[int]], list[int]]:
    """Crop boxes [x0, y0, x1, y1] (exclusive) and their layer indices.

    Layer 0 is the whole image; layer i >= 1 has (2^i)^2 overlapping crops,
    with overlap ``int(overlap_ratio * short_side * 2 / 2^i)`` pixels and
    crop length ``ceil((overlap * (n - 1) + length) / n)``; crops are listed
    with x0 in the outer loop and y0 in the inner loop.
    """
    im_h, im_w = int(im_size[0]), int(im_size[1])
    short_side = min(im_h, im_w)
    boxes: list[list[int]] = [[0, 0, im_w, im_h]]
    layers = [0]

    def crop_len(orig_len: int, n_crops: int, overlap: int) -> int:
        return int(math.ceil((overlap * (n_crops - 1) + orig_len) / n_crops))

    for i_layer in range(int(n_layers)):
        n_crops = 2 ** (i_layer + 1)
        overlap = int(overlap_ratio * short_side * (2 / n_crops))
        crop_w = crop_len(im_w, n_crops, overlap)
        crop_h = crop_len(im_h, n_crops, overlap)
        x0s = [int((crop_w - overlap) * i) for i in range(n_crops)]
        y0s = [int((crop_h - overlap) * i) for i in range(n_crops)]
        for x0, y0 in product(x0s, y0s):
            boxes.append([x0, y0, min(x0 + crop_w, im_w), min(y0 + crop_h, im_h)])
            layers.append(i_layer + 1)
    return boxes, layers


def stability_score(logits: np.ndarray, mask_threshold: float, offset: float) -> np.ndarray:
    """float32 (K,) stability of mask logits (K, H, W).

    ``|logits > t + offset| / |logits > t - offset|`` (t = mask_threshold):
    the IoU of the masks thresholded high and low (one contains the other).
    A mask empty even at the low threshold scores 0 (SAM divides 0 by 0 and
    gets NaN, which fails every threshold just the same).
    """
    logits = np.asarray(logits)
    if logits.shape[0] == 0:
        return np.zeros(0, np.float32)
    inter = np.count_nonzero(logits > (mask_threshold + offset), axis=(1, 2))
    union = np.count_nonzero(logits > (mask_threshold - offset), axis=(1, 2))
    out = np.zeros(len(inter), np.float32)
    ok = union > 0
    out[ok] = inter[ok] / union[ok]
    return out


def masks_to_boxes(masks: np.ndarray) -> np.ndarray:
    """int64 (K, 4) inclusive XYXY boxes of bool masks (K, H, W); [0, 0, 0, 0] when empty."""
    masks = np.asarray(masks, bool)
    k, h, w = masks.shape
    out = np.zeros((k, 4), np.int64)
    if k == 0 or h == 0 or w == 0:
        return out
    rows = masks.any(axis=2)
    cols = masks.any(axis=1)
    nonempty = rows.any(axis=1)
    out[:, 0] = cols.argmax(axis=1)
    out[:, 1] = rows.argmax(axis=1)
    out[:, 2] = w - 1 - cols[:, ::-1].argmax(axis=1)
    out[:, 3] = h - 1 - rows[:, ::-1].argmax(axis=1)
    out[~nonempty] = 0
    return out


def box_area(boxes: np.ndarray) -> np.ndarray:
    """float64 (N,) areas ``(x1 - x0) * (y1 - y0)`` of XYXY boxes (N, 4)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    return (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """float64 (N, M) IoU of XYXY boxes a (N, 4) and b (M, 4); 0 where the union is 0."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    wh = np.clip(rb - lt, 0.0, None)
    inter = wh[..., 0] * wh[..., 1]
    union = box_area(a)[:, None] + box_area(b)[None, :] - inter
    out = np.zeros_like(inter)
    np.divide(inter, union, out=out, where=union > 0)
    return out


def nms(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy non-maximum suppression; int64 indices of the kept boxes, best first.

    Boxes are visited by decreasing score (ties: lower index first, the
    stable sort torchvision's CPU kernel uses); a box is dropped when its IoU
    with an already kept box is strictly greater than ``iou_threshold``.
    As in torchvision's kernel (SAM passes ``boxes.float()``), the IoU is
    computed in float32 and compared with the threshold as a double: an IoU
    of exactly 3/10 becomes 0.3f = 0.30000001 > 0.3 and suppresses.
    """
    boxes = np.asarray(boxes, np.float32).reshape(-1, 4)
    scores = np.asarray(scores).reshape(-1)
    if len(boxes) != len(scores):
        raise ValueError(f"{len(boxes)} boxes but {len(scores)} scores")
    order = np.argsort(-scores.astype(np.float64), kind="stable")
    x0, y0, x1, y1 = (np.ascontiguousarray(boxes[:, i]) for i in range(4))
    areas = (x1 - x0) * (y1 - y0)
    zero = np.float32(0)
    threshold = float(iou_threshold)
    suppressed = np.zeros(len(order), bool)
    keep: list[int] = []
    for pos in range(len(order)):
        i = int(order[pos])
        if suppressed[i]:
            continue
        keep.append(i)
        rest = order[pos + 1 :]
        rest = rest[~suppressed[rest]]
        if not len(rest):
            continue
        w = np.maximum(zero, np.minimum(x1[i], x1[rest]) - np.maximum(x0[i], x0[rest]))
        h = np.maximum(zero, np.minimum(y1[i], y1[rest]) - np.maximum(y0[i], y0[rest]))
        inter = w * h
        with np.errstate(invalid="ignore", divide="ignore"):
            iou = inter / (areas[i] + areas[rest] - inter)  # 0/0 = NaN never suppresses
        suppressed[rest[iou.astype(np.float64) > threshold]] = True
    return np.asarray(keep, np.int64)


def is_box_near_crop_edge(boxes: np.ndarray, crop_box, orig_box, atol: float = 20.0) -> np.ndarray:
    """bool (N,): the crop-frame box (N, 4) lies within ``atol`` pixels of an
    edge of ``crop_box`` that is not also within ``atol`` of the image edge
    ``orig_box`` (coordinate-wise, after uncropping; SAM drops such masks as
    probably cut off by the crop)."""
    crop = np.asarray(crop_box, np.float64)
    orig = np.asarray(orig_box, np.float64)
    b = uncrop_boxes(np.asarray(boxes, np.float64).reshape(-1, 4), crop_box)
    near_crop = np.abs(b - crop[None, :]) <= atol
    near_image = np.abs(b - orig[None, :]) <= atol
    return np.any(near_crop & ~near_image, axis=1)


def uncrop_boxes(boxes: np.ndarray, crop_box) -> np.ndarray:
    """XYXY boxes (N, 4) moved from the crop frame to the image frame."""
    x0, y0 = crop_box[0], crop_box[1]
    return np.asarray(boxes) + np.asarray([x0, y0, x0, y0], dtype=np.asarray(boxes).dtype)


def uncrop_points(points: np.ndarray, crop_box) -> np.ndarray:
    """(x, y) points (N, 2) moved from the crop frame to the image frame."""
    x0, y0 = crop_box[0], crop_box[1]
    return np.asarray(points) + np.asarray([x0, y0], dtype=np.asarray(points).dtype)


def uncrop_masks(masks: np.ndarray, crop_box, orig_h: int, orig_w: int) -> np.ndarray:
    """bool (K, orig_h, orig_w): crop-frame masks (K, h, w) pasted at the crop's place."""
    x0, y0, x1, y1 = (int(v) for v in crop_box)
    masks = np.asarray(masks, bool)
    if (x0, y0, x1, y1) == (0, 0, orig_w, orig_h):
        return masks
    out = np.zeros((masks.shape[0], orig_h, orig_w), bool)
    out[:, y0:y1, x0:x1] = masks
    return out


def remove_small_regions(mask: np.ndarray, area_thresh: float, mode: str) -> tuple[np.ndarray, bool]:
    """Fill small holes (mode "holes") or drop small islands (mode "islands").

    mask: bool (H, W).  Regions are 8-connected components (OpenCV
    ``connectedComponentsWithStats``) of the background ("holes") or of the
    mask ("islands"); those with fewer than ``area_thresh`` pixels are filled
    / removed.  Background regions touching the border count as holes too,
    as in SAM.  When every island is small, the largest one is kept.
    Returns (new mask, whether it changed).
    """
    if mode not in ("holes", "islands"):
        raise ValueError(f"mode must be 'holes' or 'islands', got {mode!r}")
    mask = np.asarray(mask, bool)
    holes = mode == "holes"
    working = (holes ^ mask).astype(np.uint8)
    n_labels, regions, stats, _ = cv2.connectedComponentsWithStats(working, connectivity=8)
    sizes = stats[1:, cv2.CC_STAT_AREA]
    small = [i + 1 for i, s in enumerate(sizes) if s < area_thresh]
    if not small:
        return mask, False
    fill = [0] + small
    if not holes:
        fill = [i for i in range(n_labels) if i not in fill]
        if not fill:
            fill = [int(np.argmax(sizes)) + 1]
    return np.isin(regions, fill), True
