"""Image pre- and post-processing for the ONNX model probes (pure numpy / OpenCV).

Conventions:

* Images handed to the probes are RGB ``(H, W, 3)``, either uint8 0..255 or
  float 0..1 (:func:`as_rgb01` converts both to float32 0..1; floats slightly
  outside [0, 1], e.g. from a renderer, are clipped).
* Model inputs are float32 ``(1, 3, H, W)`` (NCHW).
* Image resizing uses the *antialiased bilinear* (triangle) filter of PIL's
  ``Image.resize(..., BILINEAR)`` and of torch's
  ``interpolate(..., mode="bilinear", antialias=True)``.
  segment-anything (``ResizeLongestSide.apply_image``) and GroundingDINO
  (``T.RandomResize``) resize a uint8 image through PIL: the image is
  rounded to uint8 (exact for images that came as uint8; a float render is
  quantised as those pipelines require) and resized by
  :func:`resize_uint8_pil`, PIL's 8-bit fixed-point arithmetic re-done in
  numpy, bit for bit (tests/test_probes_pil_resize.py against the installed
  Pillow).  SAM2 (``torchvision.transforms.Resize`` on a float tensor)
  resizes in float: :func:`resize_antialias`, float32.
* Mask-logit upsampling uses plain bilinear interpolation with half-pixel
  centres and edge clamping (torch ``F.interpolate(mode="bilinear",
  align_corners=False)``, as SAM / SAM2 ``postprocess_masks``), through
  ``cv2.resize(..., INTER_LINEAR)``, which computes the same thing.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from r360gpu.errors import InputError

__all__ = [
    "SAM_PIXEL_MEAN",
    "SAM_PIXEL_STD",
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "as_rgb01",
    "resize_antialias",
    "to_uint8",
    "resize_uint8_pil",
    "longest_side_shape",
    "sam_encoder_input",
    "sam_resized_image",
    "sam2_encoder_input",
    "dino_input_shape",
    "dino_encoder_input",
    "resize_logits",
    "sam_logits_to_image",
]

#: segment-anything pixel statistics, on the 0..255 scale.
SAM_PIXEL_MEAN = (123.675, 116.28, 103.53)
SAM_PIXEL_STD = (58.395, 57.12, 57.375)
#: ImageNet statistics on the 0..1 scale (SAM2, GroundingDINO).
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def as_rgb01(image, what: str = "image") -> np.ndarray:
    """float32 (H, W, 3) in [0, 1] from an RGB uint8 (0..255) or float (0..1) image.

    Other integer types are rejected (their range is ambiguous), as are
    non-finite values and a wrong shape: InputError naming ``what``.
    """
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InputError(f"{what} must be an RGB (H, W, 3) array, got shape {arr.shape}")
    if arr.dtype == np.uint8:
        return arr.astype(np.float32) * np.float32(1.0 / 255.0)
    if arr.dtype.kind == "f":
        out = arr.astype(np.float32)
        if not np.isfinite(out).all():
            raise InputError(f"{what} has NaN or infinite values")
        return np.clip(out, 0.0, 1.0)
    raise InputError(f"{what} must be uint8 (0..255) or float (0..1), got {arr.dtype}")


def _aa_taps(in_size: int, out_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Source indices and weights, each (out_size, K), of the triangle filter.

    PIL / torch-antialias recipe: output pixel i has its centre at
    ``c = (i + 0.5) * scale`` in input pixels (scale = in / out); the filter
    half-width is ``max(scale, 1)``; input pixel j gets weight
    ``max(0, 1 - |(j + 0.5 - c)| / max(scale, 1))`` over the window
    ``[int(c - support + 0.5), int(c + support + 0.5))`` clipped to the
    image; weights are normalised to sum to 1.
    """
    scale = in_size / out_size
    support = max(scale, 1.0)
    centers = (np.arange(out_size, dtype=np.float64) + 0.5) * scale
    # int() in PIL truncates towards zero; max(., 0) makes the sign moot.
    lo = np.maximum(np.trunc(centers - support + 0.5).astype(np.int64), 0)
    hi = np.minimum(np.trunc(centers + support + 0.5).astype(np.int64), in_size)
    k = int((hi - lo).max())
    idx = lo[:, None] + np.arange(k, dtype=np.int64)[None, :]
    weights = np.maximum(0.0, 1.0 - np.abs((idx + 0.5 - centers[:, None]) / support))
    weights[idx >= hi[:, None]] = 0.0
    total = weights.sum(axis=1, keepdims=True)
    weights /= np.where(total > 0, total, 1.0)
    return np.minimum(idx, in_size - 1), weights.astype(np.float32)


def resize_antialias(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Antialiased bilinear resize of a float (H, W) or (H, W, C) image to size (H', W').

    Returns float32.  Identity when the size does not change.  Downscaling
    averages over the triangle filter's footprint (no aliasing); upscaling is
    plain bilinear with half-pixel centres and edge clamping.
    """
    img = np.asarray(image, dtype=np.float32)
    out_h, out_w = int(size[0]), int(size[1])
    if out_h < 1 or out_w < 1:
        raise ValueError(f"output size must be positive, got {size}")
    in_h, in_w = img.shape[:2]
    if (in_h, in_w) != (out_h, out_w):
        if in_w != out_w:
            idx, w = _aa_taps(in_w, out_w)
            tmp = np.zeros((in_h, out_w) + img.shape[2:], np.float32)
            shape = (1, out_w) + (1,) * (img.ndim - 2)
            for k in range(idx.shape[1]):
                tmp += w[:, k].reshape(shape) * img[:, idx[:, k]]
            img = tmp
        if in_h != out_h:
            idx, w = _aa_taps(in_h, out_h)
            tmp = np.zeros((out_h,) + img.shape[1:], np.float32)
            shape = (out_h,) + (1,) * (img.ndim - 1)
            for k in range(idx.shape[1]):
                tmp += w[:, k].reshape(shape) * img[idx[:, k]]
            img = tmp
    return np.ascontiguousarray(img)


def to_uint8(image01: np.ndarray) -> np.ndarray:
    """uint8 (H, W, C) from float 0..1: ``floor(x * 255 + 0.5)``, clipped.

    Inverts :func:`as_rgb01` exactly on images that came as uint8 (checked
    for all 256 values in the tests).
    """
    x = np.asarray(image01, np.float32)
    return np.clip(np.floor(x * np.float32(255.0) + np.float32(0.5)), 0, 255).astype(np.uint8)


#: Fractional bits of PIL's 8-bit resampling coefficients (Resample.c: 32 - 8 - 2).
_PIL_PRECISION_BITS = 22


def _pil_bilinear_coeffs(in_size: int, out_size: int) -> tuple[np.ndarray, np.ndarray]:
    """Source indices and int32 fixed-point weights, each (out_size, K), of PIL's
    ``precompute_coeffs`` + ``normalize_coeffs_8bpc`` for the bilinear filter,
    with its float64 operations in its order (so the rounding is the same)."""
    scale = float(in_size) / out_size
    filterscale = max(scale, 1.0)
    support = 1.0 * filterscale  # the bilinear filter's support is 1
    inv = 1.0 / filterscale
    ksize = int(math.ceil(support)) * 2 + 1
    centers = (np.arange(out_size, dtype=np.float64) + 0.5) * scale
    # C's (int) truncates towards zero; negatives are clamped to 0 anyway.
    xmin = np.maximum((centers - support + 0.5).astype(np.int64), 0)
    count = np.minimum((centers + support + 0.5).astype(np.int64), in_size) - xmin
    taps = xmin[:, None] + np.arange(ksize, dtype=np.int64)[None, :]
    w = np.maximum(0.0, 1.0 - np.abs(((taps.astype(np.float64) - centers[:, None]) + 0.5) * inv))
    w[np.arange(ksize)[None, :] >= count[:, None]] = 0.0
    total = np.zeros(out_size, np.float64)
    for k in range(ksize):  # summed left to right, as the C loop
        total = total + w[:, k]
    w = w / np.where(total != 0.0, total, 1.0)[:, None]
    fixed = np.trunc(0.5 + w * float(1 << _PIL_PRECISION_BITS)).astype(np.int32)
    return np.minimum(taps, in_size - 1), fixed


def _pil_pass(image: np.ndarray, axis: int, out_size: int) -> np.ndarray:
    """One 8-bit resampling pass of PIL along ``axis`` (1: horizontal, 0: vertical),
    rounding to uint8 as PIL's ``clip8`` does."""
    idx, coef = _pil_bilinear_coeffs(image.shape[axis], out_size)
    shape = [1] * image.ndim
    shape[axis] = out_size
    out_shape = image.shape[:axis] + (out_size,) + image.shape[axis + 1 :]
    # At most 255 * (2**22 + K) + 2**21 < 2**31: int32 cannot overflow.
    acc = np.full(out_shape, 1 << (_PIL_PRECISION_BITS - 1), np.int32)
    for k in range(idx.shape[1]):
        acc += np.take(image, idx[:, k], axis=axis).astype(np.int32) * coef[:, k].reshape(shape)
    return np.clip(acc >> _PIL_PRECISION_BITS, 0, 255).astype(np.uint8)


def resize_uint8_pil(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """PIL's ``Image.resize((W', H'), BILINEAR)`` of a uint8 (H, W) or (H, W, C) image.

    Pillow's 8-bit path: float64 triangle-filter weights rounded to 22-bit
    fixed point, one pass per axis, each rounded and clipped to uint8 (a pass
    is skipped when that side keeps its size).  Horizontal pass first, except
    for images over 100 times taller than wide that shrink vertically
    (Pillow 12.2: "Resize tall images vertically first").  Bit for bit equal
    to Pillow 12.2 / 12.3 (tests/test_probes_pil_resize.py); Pillow 13 chooses
    the pass order by its own rule, and then its pixels are those of the
    other order (at most 1 grey level apart), as are Pillow <= 12.1's for
    those tall images.
    """
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise ValueError(f"resize_uint8_pil takes uint8, got {img.dtype}")
    out_h, out_w = int(size[0]), int(size[1])
    if out_h < 1 or out_w < 1:
        raise ValueError(f"output size must be positive, got {size}")
    axes = [(1, out_w), (0, out_h)]
    if img.shape[0] > img.shape[1] * 100 and out_h < img.shape[0]:
        axes.reverse()
    for axis, n in axes:
        if img.shape[axis] != n:
            img = _pil_pass(img, axis, n)
    return np.ascontiguousarray(img)


def longest_side_shape(height: int, width: int, long_side: int) -> tuple[int, int]:
    """(H', W') with the longest side scaled to ``long_side``, rounded half up.

    segment-anything's ``ResizeLongestSide.get_preprocess_shape``.
    """
    scale = long_side * 1.0 / max(height, width)
    return int(height * scale + 0.5), int(width * scale + 0.5)


def _normalise_chw(image: np.ndarray, mean, std) -> np.ndarray:
    mean = np.asarray(mean, np.float32)
    std = np.asarray(std, np.float32)
    return ((image - mean) / std).transpose(2, 0, 1)


def sam_resized_image(image01: np.ndarray, long_side: int = 1024) -> np.ndarray:
    """float32 (H', W', 3) on the 0..255 scale (integers), longest side resized to ``long_side``.

    segment-anything's ``ResizeLongestSide.apply_image``: the uint8 image
    resized by PIL (:func:`resize_uint8_pil`).  Also the input of encoders
    exported with their preprocessing inside (samexporter
    ``--use-preprocess``: input ``input_image`` of shape (H, W, 3)); they
    normalise and pad themselves.
    """
    h, w = image01.shape[:2]
    resized = resize_uint8_pil(to_uint8(image01), longest_side_shape(h, w, long_side))
    return resized.astype(np.float32)


def sam_encoder_input(image01: np.ndarray, long_side: int = 1024) -> tuple[np.ndarray, tuple[int, int]]:
    """SAM / MobileSAM encoder input and the resized (unpadded) size.

    image01: float32 (H, W, 3) in [0, 1].  Returns float32 (1, 3, S, S),
    S = ``long_side``: longest side resized to S, normalised with
    :data:`SAM_PIXEL_MEAN` / :data:`SAM_PIXEL_STD` on the 0..255 scale, then
    zero-padded at the bottom and right (as ``Sam.preprocess``), and the
    resized size (H', W').
    """
    resized = sam_resized_image(image01, long_side)
    nh, nw = resized.shape[:2]
    out = np.zeros((1, 3, long_side, long_side), np.float32)
    out[0, :, :nh, :nw] = _normalise_chw(resized, SAM_PIXEL_MEAN, SAM_PIXEL_STD)
    return out, (nh, nw)


def sam2_encoder_input(image01: np.ndarray, size: tuple[int, int] = (1024, 1024)) -> np.ndarray:
    """SAM2 encoder input: float32 (1, 3, S, S), the image resized to ``size``
    (aspect ratio not kept, as ``SAM2Transforms``) and normalised with the
    ImageNet mean / std on the 0..1 scale."""
    resized = resize_antialias(image01, size)
    return _normalise_chw(resized, IMAGENET_MEAN, IMAGENET_STD)[None].astype(np.float32)


def dino_input_shape(height: int, width: int, size: int = 800, max_size: int | None = 1333) -> tuple[int, int]:
    """GroundingDINO's ``RandomResize([size], max_size)`` output (H', W').

    Shorter side -> ``size`` unless the longer side would exceed
    ``max_size``, in which case the shorter side becomes
    ``round(max_size * short / long)``; the longer side is then truncated
    (``get_size_with_aspect_ratio`` of GroundingDINO's transforms).
    """
    h, w = int(height), int(width)
    if max_size is not None:
        short, long = float(min(h, w)), float(max(h, w))
        if long / short * size > max_size:
            size = int(round(max_size * short / long))
    if (w <= h and w == size) or (h <= w and h == size):
        return h, w
    if w < h:
        return int(size * h / w), size
    return size, int(size * w / h)


def dino_encoder_input(image01: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """GroundingDINO image input: float32 (1, 3, H', W'), resized to ``shape``
    and normalised with the ImageNet mean / std on the 0..1 scale.

    As GroundingDINO's transforms: the uint8 image resized by PIL
    (:func:`resize_uint8_pil`), ``ToTensor`` (float32 division by 255), then
    ``Normalize``.
    """
    resized = resize_uint8_pil(to_uint8(image01), shape).astype(np.float32) / np.float32(255.0)
    return _normalise_chw(resized, IMAGENET_MEAN, IMAGENET_STD)[None].astype(np.float32)


def resize_logits(logits: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Bilinear resize (half-pixel centres, no antialias) of float (K, h, w) to (K, H, W).

    Matches torch ``F.interpolate(mode="bilinear", align_corners=False)``.
    Returns float32.
    """
    logits = np.asarray(logits, np.float32)
    out_h, out_w = int(size[0]), int(size[1])
    if logits.shape[1:] == (out_h, out_w):
        return logits.copy()
    out = np.empty((logits.shape[0], out_h, out_w), np.float32)
    for k in range(logits.shape[0]):
        # One 2-D call per mask: stacking masks as channels costs more in transposes than it saves.
        cv2.resize(logits[k], (out_w, out_h), dst=out[k], interpolation=cv2.INTER_LINEAR)
    return out


def sam_logits_to_image(
    low_res: np.ndarray, input_size: int, resized_size: tuple[int, int], image_size: tuple[int, int]
) -> np.ndarray:
    """SAM's ``postprocess_masks`` on low-resolution logits (K, h, w) -> (K, H, W) float32.

    Upsample to the padded encoder frame (input_size x input_size), drop the
    padding (keep the top-left ``resized_size``), resize to ``image_size``.
    """
    low_res = np.asarray(low_res, np.float32)
    nh, nw = int(resized_size[0]), int(resized_size[1])
    out_h, out_w = int(image_size[0]), int(image_size[1])
    out = np.empty((low_res.shape[0], out_h, out_w), np.float32)
    frame = np.empty((input_size, input_size), np.float32)
    for k in range(low_res.shape[0]):
        cv2.resize(low_res[k], (input_size, input_size), dst=frame, interpolation=cv2.INTER_LINEAR)
        cv2.resize(frame[:nh, :nw], (out_w, out_h), dst=out[k], interpolation=cv2.INTER_LINEAR)
    return out
