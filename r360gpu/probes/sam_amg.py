"""Structural probe: SAM / SAM2 automatic mask generation on ONNX models.

The algorithm is segment-anything's ``SamAutomaticMaskGenerator`` (SAM2's
``SAM2AutomaticMaskGenerator`` is the same with other defaults), re-written
on numpy + onnxruntime:

1. Crops: the whole image, plus ``crop_n_layers`` layers of overlapping
   crops (:func:`amg_utils.generate_crop_boxes`).  Each crop is encoded on
   its own.
2. Per crop, a grid of ``points_per_side``^2 cell-centre points (fewer on
   deeper layers: ``crop_n_points_downscale_factor``), decoded in batches of
   ``points_per_batch`` with multimask output (3 masks per point).
3. Per mask: keep if predicted IoU > ``pred_iou_thresh``; upsample the
   logits to the crop size; keep if the stability score (offset
   ``stability_score_offset``) >= ``stability_score_thresh``; threshold at
   ``mask_threshold``; drop masks whose box is within 20 px of a crop edge
   that is not an image edge.
4. Box NMS (IoU > ``box_nms_thresh``, score = predicted IoU) per crop; with
   several crops, NMS across crops (``crop_nms_thresh``) preferring smaller
   crops.
5. SAM only, with ``min_mask_region_area`` > 0: fill holes and remove
   islands smaller than that (8-connectivity), then NMS again (threshold
   max(box_nms_thresh, crop_nms_thresh)) preferring unchanged masks.  SAM2's
   generator has no such step (there the parameter drives the predictor's
   low-resolution hole / sprinkle filling, below).

Differences from the torch originals, all from running the exported graphs:
the multimask outputs come from the ONNX decoder (tokens 1..3 of a SAM
decoder's four); a decoder exported with ``--return-single-mask`` yields one
mask per point (warned); SAM's image resize is PIL's on the uint8 image, bit
for bit, and SAM2's a float32 version of torch's antialiased bilinear resize
(see :mod:`r360gpu.probes.preprocess`); SAM2's optional
hole / sprinkle filling of low-resolution logits (its CUDA extension, only
active when ``min_mask_region_area`` > 0; skipped by SAM2 itself where the
extension does not load, e.g. on CPU) is not reproduced.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from r360gpu.errors import InputError, R360Warning
from r360gpu.probes import amg_utils as au
from r360gpu.probes.base import MaskSet, ProbeView, StructuralProbe
from r360gpu.probes.onnx_models import SamEmbedding, SamModels
from r360gpu.probes.preprocess import as_rgb01

__all__ = ["AmgParams", "AmgResult", "generate_masks", "SamAmgProbe"]

#: Predicted-IoU threshold defaults of the two generators.
DEFAULT_PRED_IOU_THRESH = {"sam": 0.88, "sam2": 0.8}
# Masks upsampled to crop size at once: bounds the float32 (chunk, H, W) buffer.
_UPSAMPLE_CHUNK = 16


@dataclass(frozen=True)
class AmgParams:
    """Automatic-mask-generator parameters (SAM's defaults).

    pred_iou_thresh None means the model family's default: 0.88 for SAM /
    MobileSAM, 0.8 for SAM2 (:meth:`resolved` fills it in).
    Thresholds are on the model's predicted IoU (0..1), the stability score
    (0..1) and the mask logits; ``min_mask_region_area`` is in pixels.
    """

    points_per_side: int = 32
    points_per_batch: int = 64
    pred_iou_thresh: float | None = None
    stability_score_thresh: float = 0.95
    stability_score_offset: float = 1.0
    mask_threshold: float = 0.0
    box_nms_thresh: float = 0.7
    crop_n_layers: int = 0
    crop_nms_thresh: float = 0.7
    crop_overlap_ratio: float = 512 / 1500
    crop_n_points_downscale_factor: int = 1
    min_mask_region_area: int = 0

    def __post_init__(self) -> None:
        def need(ok: bool, what: str) -> None:
            if not ok:
                raise InputError(f"automatic mask generator: {what}")

        for name in ("points_per_side", "points_per_batch", "crop_n_points_downscale_factor"):
            value = getattr(self, name)
            need(
                isinstance(value, int) and not isinstance(value, bool) and value >= 1,
                f"{name} must be an integer >= 1, got {value!r}",
            )
        for name in ("crop_n_layers", "min_mask_region_area"):
            value = getattr(self, name)
            need(
                isinstance(value, int) and not isinstance(value, bool) and value >= 0,
                f"{name} must be an integer >= 0, got {value!r}",
            )
        for name in ("stability_score_thresh", "box_nms_thresh", "crop_nms_thresh", "crop_overlap_ratio"):
            value = getattr(self, name)
            need(_is_real(value) and 0.0 <= value <= 1.0, f"{name} must be in [0, 1], got {value!r}")
        if self.pred_iou_thresh is not None:
            need(
                _is_real(self.pred_iou_thresh) and 0.0 <= self.pred_iou_thresh <= 1.0,
                f"pred_iou_thresh must be in [0, 1], got {self.pred_iou_thresh!r}",
            )
        need(
            _is_real(self.stability_score_offset) and self.stability_score_offset >= 0,
            f"stability_score_offset must be >= 0, got {self.stability_score_offset!r}",
        )
        need(
            _is_real(self.mask_threshold) and math.isfinite(self.mask_threshold),
            f"mask_threshold must be a finite number, got {self.mask_threshold!r}",
        )
        deepest = self.points_per_side // self.crop_n_points_downscale_factor**self.crop_n_layers
        need(
            deepest >= 1,
            f"crop layer {self.crop_n_layers} would have no points "
            f"({self.points_per_side} per side / {self.crop_n_points_downscale_factor}^{self.crop_n_layers})",
        )

    def resolved(self, variant: str) -> "AmgParams":
        """A copy with ``pred_iou_thresh`` set to the family default when None."""
        if self.pred_iou_thresh is not None:
            return self
        return dataclasses.replace(self, pred_iou_thresh=DEFAULT_PRED_IOU_THRESH[variant])

    def as_dict(self) -> dict:
        """Field name -> value (JSON-able), for ``describe()``."""
        return dataclasses.asdict(self)


def _is_real(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True, eq=False)
class AmgResult:
    """Masks of one image, in the order the last NMS kept them (best first).

    masks: bool (K, H, W).  iou_preds, stability: float32 (K,).
    boxes: int64 (K, 4) inclusive XYXY of each mask, image pixels.
    points: float64 (K, 2) (x, y) prompt point of each mask, image pixels.
    crop_boxes: int64 (K, 4) exclusive XYXY crop each mask came from.
    """

    masks: np.ndarray
    iou_preds: np.ndarray
    stability: np.ndarray
    boxes: np.ndarray
    points: np.ndarray
    crop_boxes: np.ndarray

    @property
    def count(self) -> int:
        return int(self.masks.shape[0])


@dataclass
class _Found:
    """Masks kept so far, each stored cut to its box (image frame after uncropping)."""

    boxes: list = field(default_factory=list)
    iou: list = field(default_factory=list)
    stability: list = field(default_factory=list)
    points: list = field(default_factory=list)
    crops: list = field(default_factory=list)
    cutouts: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.iou)

    def take(self, keep) -> "_Found":
        keep = [int(i) for i in keep]
        return _Found(*([getattr(self, f.name)[i] for i in keep] for f in dataclasses.fields(self)))

    def extend(self, other: "_Found") -> None:
        for f in dataclasses.fields(self):
            getattr(self, f.name).extend(getattr(other, f.name))

    def box_array(self) -> np.ndarray:
        return np.asarray(self.boxes, np.int64).reshape(-1, 4)


def generate_masks(models: SamModels, image, params: AmgParams | None = None) -> AmgResult:
    """Run the automatic mask generator (module docstring) on one RGB image.

    image: (H, W, 3) uint8 0..255 or float 0..1.  params: None for the
    defaults; ``pred_iou_thresh`` None takes the model family's default.
    """
    params = (params or AmgParams()).resolved(models.variant)
    image01 = as_rgb01(image)
    h, w = image01.shape[:2]
    crop_boxes, layers = au.generate_crop_boxes((h, w), params.crop_n_layers, params.crop_overlap_ratio)
    grids = au.build_all_layer_point_grids(
        params.points_per_side, params.crop_n_layers, params.crop_n_points_downscale_factor
    )
    found = _Found()
    for crop_box, layer in zip(crop_boxes, layers):
        found.extend(_process_crop(models, image01, crop_box, grids[layer], params))
    if len(crop_boxes) > 1 and len(found):
        # Prefer masks from smaller crops; 1 / area in float32 as SAM's
        # ``1 / box_area(int64 crop boxes)`` (equal areas tie, stable order).
        scores = np.float32(1.0) / au.box_area(np.asarray(found.crops)).astype(np.float32)
        found = found.take(au.nms(found.box_array(), scores, params.crop_nms_thresh))
    masks = _paste(found, h, w)
    iou = np.asarray(found.iou, np.float32)
    boxes = found.box_array()
    # SAM only: SAM2AutomaticMaskGenerator.generate has no postprocess_small_regions step; its
    # min_mask_region_area only sets the predictor's low-res hole / sprinkle filling (not reproduced).
    if params.min_mask_region_area > 0 and len(found) and models.variant == "sam":
        masks, boxes, keep = _remove_small_regions(
            masks, params.min_mask_region_area, max(params.box_nms_thresh, params.crop_nms_thresh)
        )
        found = found.take(keep)
        iou = iou[keep]
    return AmgResult(
        masks=masks,
        iou_preds=iou,
        stability=np.asarray(found.stability, np.float32),
        boxes=boxes,
        points=np.asarray(found.points, np.float64).reshape(-1, 2),
        crop_boxes=np.asarray(found.crops, np.int64).reshape(-1, 4),
    )


def _process_crop(models: SamModels, image01: np.ndarray, crop_box, grid: np.ndarray, params: AmgParams) -> _Found:
    x0, y0, x1, y1 = crop_box
    crop = image01[y0:y1, x0:x1]
    ch, cw = crop.shape[:2]
    orig_box = [0, 0, image01.shape[1], image01.shape[0]]
    embedding = models.embed(crop)
    points = grid * np.array([cw, ch], np.float64)
    found = _Found()
    for start in range(0, len(points), params.points_per_batch):
        batch = points[start : start + params.points_per_batch]
        found.extend(_process_batch(models, embedding, batch, crop_box, orig_box, params))
    if not len(found):
        return found
    found = found.take(au.nms(found.box_array(), np.asarray(found.iou, np.float64), params.box_nms_thresh))
    found.boxes = [au.uncrop_boxes(b, crop_box) for b in found.boxes]
    found.points = [au.uncrop_points(p, crop_box) for p in found.points]
    return found


def _process_batch(
    models: SamModels, embedding: SamEmbedding, points: np.ndarray, crop_box, orig_box, params: AmgParams
) -> _Found:
    """Masks of one batch of points, in the crop frame (boxes, points, cut-outs)."""
    decoded = models.predict_points(embedding, points)
    if decoded.masks_per_prompt == 1:
        warnings.warn(
            f"{models.decoder.path}: the SAM decoder returns one mask per prompt (exported with "
            "--return-single-mask?); the automatic mask generator normally uses three per point",
            R360Warning,
            stacklevel=5,
        )
    logits, iou = decoded.multimask()
    per_point = logits.shape[1]
    logits = logits.reshape((-1,) + logits.shape[2:])
    iou = iou.reshape(-1)
    point_of = np.repeat(points, per_point, axis=0)
    if params.pred_iou_thresh > 0:
        candidates = np.flatnonzero(iou > params.pred_iou_thresh)
    else:
        candidates = np.arange(len(iou))
    found = _Found()
    for start in range(0, len(candidates), _UPSAMPLE_CHUNK):
        idx = candidates[start : start + _UPSAMPLE_CHUNK]
        full = models.logits_to_image(embedding, logits[idx], decoded.low_res)
        stability = au.stability_score(full, params.mask_threshold, params.stability_score_offset)
        if params.stability_score_thresh > 0:
            stable = np.flatnonzero(stability >= params.stability_score_thresh)
        else:
            stable = np.arange(len(idx))
        if not len(stable):
            continue
        masks = full[stable] > params.mask_threshold
        del full
        boxes = au.masks_to_boxes(masks)
        near = au.is_box_near_crop_edge(boxes, crop_box, orig_box)
        for j in np.flatnonzero(~near):
            i = idx[stable[j]]
            bx0, by0, bx1, by1 = (int(v) for v in boxes[j])
            found.boxes.append(boxes[j])
            found.iou.append(float(iou[i]))
            found.stability.append(float(stability[stable[j]]))
            found.points.append(point_of[i])
            found.crops.append([int(v) for v in crop_box])
            found.cutouts.append(masks[j, by0 : by1 + 1, bx0 : bx1 + 1].copy())
    return found


def _paste(found: _Found, height: int, width: int) -> np.ndarray:
    """bool (K, H, W) full masks from the box cut-outs (image-frame boxes)."""
    masks = np.zeros((len(found), height, width), bool)
    for k, (box, cutout) in enumerate(zip(found.boxes, found.cutouts)):
        x0, y0 = int(box[0]), int(box[1])
        masks[k, y0 : y0 + cutout.shape[0], x0 : x0 + cutout.shape[1]] = cutout
    return masks


def _remove_small_regions(masks: np.ndarray, min_area: int, nms_thresh: float):
    """SAM's ``postprocess_small_regions``: (masks, boxes, kept indices).

    Holes then islands smaller than ``min_area`` pixels are fixed; NMS on the
    new boxes scores unchanged masks 1 and changed ones 0.
    """
    fixed = np.empty_like(masks)
    scores = np.empty(len(masks), np.float64)
    for k, mask in enumerate(masks):
        mask, changed_holes = au.remove_small_regions(mask, min_area, "holes")
        mask, changed_islands = au.remove_small_regions(mask, min_area, "islands")
        fixed[k] = mask
        scores[k] = 0.0 if (changed_holes or changed_islands) else 1.0
    boxes = au.masks_to_boxes(fixed)
    keep = au.nms(boxes, scores, nms_thresh)
    return fixed[keep], boxes[keep], keep


class SamAmgProbe(StructuralProbe):
    """Structural probe: automatic masks of a SAM / MobileSAM / SAM2 ONNX pair.

    encoder, decoder: the exported ``.onnx`` files (see
    :mod:`r360gpu.probes.onnx_models` for the supported exports).
    params: :class:`AmgParams` (None: the defaults of the model family).
    device: onnxruntime device ("cpu", "cuda", "directml", "coreml", "auto").
    name: probe name recorded in results (default "sam-amg" / "sam2-amg").

    ``predict`` gives one :class:`MaskSet` per view (scores = predicted
    IoU), from the view's RGB image (uint8 0..255 or float 0..1).
    """

    def __init__(
        self,
        encoder: str | os.PathLike,
        decoder: str | os.PathLike,
        params: AmgParams | None = None,
        device: str = "cpu",
        name: str | None = None,
    ):
        self.models = SamModels(encoder, decoder, device)
        self.amg = (params or AmgParams()).resolved(self.models.variant)
        self._name = name or f"{self.models.variant}-amg"

    @property
    def name(self) -> str:
        return self._name

    def params(self) -> dict:
        return {
            "model": "sam-automatic-mask-generator",
            **self.models.describe_models(),
            "amg": self.amg.as_dict(),
            "provider": self.models.provider,
        }

    def model_hashes(self) -> dict[str, str]:
        return self.models.digests()

    def predict(self, views: Sequence[ProbeView]) -> list[MaskSet]:
        """One MaskSet per view, at the view's size."""
        out = []
        for view in views:
            if view.image is None:
                raise InputError(
                    f"probe {self.name!r} needs the rendered image of view {view.name!r}, and none was given"
                )
            image01 = as_rgb01(view.image, f"view {view.name!r} image")
            result = generate_masks(self.models, image01, self.amg)
            out.append(MaskSet(result.masks, result.iou_preds, self.name))
        return out
