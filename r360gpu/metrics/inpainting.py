"""Inpainting quality as the removal benchmarks score it: 360-USID (AuraFusion360) and SPIn-NeRF.

These benchmarks ask "how good is what was painted in?": a method's renders at the captured
test views against photographs of the real scene without the object, over the whole image
and inside the object's mask.  The definitions are those of AuraFusion360's public
evaluation script ``aura_eval.py`` (in its ``scripts`` folder) with the 3DGS helpers
``image_utils.py`` and ``loss_utils.py`` (in its ``utils`` folder), re-derived here in float64:

* **PSNR** ``20 log10(1 / sqrt(MSE))`` per image, MSE over all pixels and the three channels
  of the [0, 1] images (``+inf`` for identical images).  (20 log10 of 1/sqrt is the same number
  as `r360gpu.metrics.fidelity.psnr_from_mse`'s 10 log10(1/MSE).)
* **SSIM** as 3DGS computes it: an 11 x 11 Gaussian window (sigma 1.5), correlation with
  *zero* padding of 5 pixels (so the map is H x W, its border windows see black), channels
  filtered apart, ``C1 = 0.01^2``, ``C2 = 0.03^2``, the mean over the whole map and the
  channels.  It differs from `r360gpu.metrics.fidelity.ssim`, which keeps only the
  windows inside the image.
* **masked PSNR** the MSE over the mask's pixels (a pixel counts where its mask value is
  non-zero: the script's ``mask.bool()``), all three channels.
* **masked SSIM** the SSIM above of both images multiplied by the mask weights.  Outside the
  mask both products are 0, where SSIM is 1, so the value grows with the unmasked area; that is
  the benchmark's definition, kept as it is.
* **LPIPS** the plain VGG export's distance of the render and the photograph, and **masked LPIPS**
  the spatial VGG export's map weighted by the mask weights, ``sum(map * w) / sum(w)``
  (`r360gpu.metrics.fidelity.masked_lpips`; NaN for an empty mask, the script's 0 / 0).  The
  script calls ``lpips`` without ``normalize``, so the [0, 1] images go in as if in [-1, 1].
* **FID** and **KID** (`SET_METRICS`) belong to a scene's image sets, not to a view: they are
  fields of `InpaintScene`, computed by `r360gpu.pipeline.inpaint`.

Mask weights are the values the script multiplies by: the mask file as PIL and torchvision's
``to_tensor`` read it, then every value above 0.5 set to 1 (`script_weights`); a value in
(0, 0.5] stays fractional.  Reading the files is `r360gpu.io.inpaint_folders`' job.

Two modes.  ``compat`` gives the script's numbers: its mask weights, an empty mask's
masked PSNR NaN and masked SSIM 1, infinite values kept in the means (``np.mean`` of the
per-view values, as it prints them).  The script computes in float32 on the GPU; the float64
values here equal a float32 model of its steps to 1e-4 (tests/test_inpainting_metrics.py).
``default`` differs where the script's number says something it should not:

* the mask is binary, any non-zero pixel inside (the project's mask rule, `r360gpu.io.masks`),
  so an anti-aliased or JPEG-noisy edge does not weigh masked SSIM with fractional values;
* an empty mask gives no masked value (``None`` with the reason), not NaN and not a perfect SSIM of 1;
* LPIPS gets the images mapped to [-1, 1], as LPIPS is defined (``normalize=True``);
* a mean over views leaves out infinite PSNRs (identical images) and counts them beside it, as
  `r360gpu.metrics.fidelity.fidelity_summary` does; it is ``inf`` only when every view is.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

import cv2
import numpy as np

from ..errors import InputError
from . import json_values
from .fidelity import SSIM_K1, SSIM_K2, SSIM_SIGMA, SSIM_WIN, gaussian_window, masked_lpips, psnr_from_mse

MODES = ("default", "compat")

#: The per-view metrics of this module, in table order, with whether higher is better.
METRICS: tuple[tuple[str, bool], ...] = (
    ("psnr", True), ("ssim", True), ("masked_psnr", True), ("masked_ssim", True), ("lpips", False),
    ("masked_lpips", False))

#: Reasons recorded for a value not computed.
EMPTY_MASK = "the object mask is empty at this view"
NO_MASKS = "no object masks for this method (give --masks)"
NO_LPIPS = "no LPIPS model given (--lpips-model, the plain VGG export)"
NO_LPIPS_SPATIAL = "no spatial LPIPS model given (--lpips-spatial-model, the spatial VGG export)"


def _check_mode(mode: str) -> None:
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")


def _pair(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(a, dtype=np.float64)
    y = np.asarray(b, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 3:
        raise InputError(f"the two images must be (H, W, C) of one shape, got {x.shape} and {y.shape}")
    return x, y


def psnr_3dgs(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR (dB) of two (H, W, 3) images in [0, 1]: ``20 log10(1 / sqrt(MSE))``; ``+inf`` when identical."""
    x, y = _pair(a, b)
    return psnr_from_mse(float(np.mean((x - y) ** 2)))


def masked_psnr(a: np.ndarray, b: np.ndarray, weights: np.ndarray) -> float:
    """PSNR over the pixels whose weight is non-zero (all channels); NaN for an empty mask, as the
    script's mean over no pixels; ``+inf`` when the images agree there."""
    x, y = _pair(a, b)
    inside = _weights(weights, x.shape) != 0
    n = int(inside.sum())
    if n == 0:
        return math.nan
    return psnr_from_mse(float(((x - y) ** 2)[inside].sum() / (n * x.shape[2])))


def _weights(weights: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != shape[:2]:
        raise InputError(f"the mask is {w.shape[1]}x{w.shape[0]} but the images are {shape[1]}x{shape[0]}")
    return w


def _filter_zero_padded(img: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Separable correlation of (H, W, C) with g x g, zero outside the image, output (H, W, C) float64."""
    out = cv2.sepFilter2D(np.ascontiguousarray(img, np.float64), cv2.CV_64F, g, g,
                          borderType=cv2.BORDER_CONSTANT)  # BORDER_CONSTANT pads with 0
    return out.reshape(img.shape)


def _moments(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, its local mean, the local mean of x^2): one image's share of the SSIM map, computed once per
    photograph when several renders are compared with it."""
    g = gaussian_window(SSIM_WIN, SSIM_SIGMA)
    return x, _filter_zero_padded(x, g), _filter_zero_padded(x * x, g)


def _ssim_map(x: np.ndarray, y: np.ndarray, y_moments=None) -> np.ndarray:
    """The SSIM map (H, W, C) float64 of 3DGS's ``loss_utils.ssim``, zero-padded."""
    c1, c2 = SSIM_K1 ** 2, SSIM_K2 ** 2
    _, mx, xx = _moments(x)
    _, my, yy = _moments(y) if y_moments is None else y_moments
    sxy = _filter_zero_padded(x * y, gaussian_window(SSIM_WIN, SSIM_SIGMA)) - mx * my
    num = (2 * mx * my + c1) * (2 * sxy + c2)
    den = (mx * mx + my * my + c1) * ((xx - mx * mx) + (yy - my * my) + c2)
    return num / den


def ssim_3dgs(a: np.ndarray, b: np.ndarray) -> float:
    """SSIM as 3DGS's ``loss_utils.ssim`` computes it (zero padding, mean over the whole map)."""
    x, y = _pair(a, b)
    return float(np.mean(_ssim_map(x, y)))


def masked_ssim(a: np.ndarray, b: np.ndarray, weights: np.ndarray) -> float:
    """`ssim_3dgs` of both images multiplied by the mask weights (1 for an empty mask).

    Both products are 0 farther than the window's radius from the mask's bounding box, where every
    map value is exactly ``(C1 C2) / (C1 C2) = 1``; the map is computed on that box only (zero padding
    stands for the zeros around it) and those ones are added: the same mean at a fraction of the cost.
    """
    x, y = _pair(a, b)
    w = _weights(weights, x.shape)
    rows, cols = np.nonzero(w)
    if rows.size == 0:
        return 1.0
    r = SSIM_WIN // 2
    h, wd, c = x.shape
    y0, y1 = max(0, int(rows.min()) - r), min(h, int(rows.max()) + r + 1)
    x0, x1 = max(0, int(cols.min()) - r), min(wd, int(cols.max()) + r + 1)
    wc = w[y0:y1, x0:x1, None]
    box = _ssim_map(x[y0:y1, x0:x1] * wc, y[y0:y1, x0:x1] * wc)
    return float((box.sum() + (h * wd * c - box.size)) / (h * wd * c))


def script_weights(values: np.ndarray) -> np.ndarray:
    """The script's mask weights from the mask tensor as ``to_tensor`` gives it (H, W): every value
    above 0.5 becomes 1, the others stay (float64)."""
    w = np.array(values, dtype=np.float64)
    w[w > 0.5] = 1.0
    return w


@dataclass
class InpaintView:
    """One method's render at one test view against the photograph.

    A metric is ``None`` when not computed; ``reasons[metric]`` then says why.  New metrics
    are new fields here, listed in `METRICS`.
    """

    view: str
    psnr: float | None = None
    ssim: float | None = None
    masked_psnr: float | None = None
    masked_ssim: float | None = None
    lpips: float | None = None
    masked_lpips: float | None = None
    mask_pixels: int | None = None
    reasons: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {f.name: (json_values.enc_float(getattr(self, f.name)) if f.name in _METRIC_NAMES
                         else getattr(self, f.name)) for f in fields(self)}


_METRIC_NAMES = frozenset(name for name, _ in METRICS)


def score_view(view: str, photo: np.ndarray, render: np.ndarray, weights: np.ndarray | None, *,
               mode: str = "default", no_mask_reason: str = NO_MASKS) -> InpaintView:
    """The metrics of one view.  photo, render: (H, W, 3) in [0, 1]; weights: (H, W) mask weights
    (`script_weights` in compat mode, a 0/1 mask in default mode) or None when there is no mask."""
    return score_views(view, photo, [render], [weights], mode=mode, no_mask_reason=no_mask_reason)[0]


def score_views(view: str, photo: np.ndarray, renders: Sequence[np.ndarray], weights: Sequence[np.ndarray | None], *,
                mode: str = "default", no_mask_reason: str = NO_MASKS, lpips=None, lpips_spatial=None
                ) -> list[InpaintView]:
    """`score_view` of several renders (methods) against one photograph, each with its mask weights;
    the photograph's share of SSIM is computed once.

    lpips: a plain `r360gpu.metrics.fidelity.LpipsModel` export (whole-image LPIPS), lpips_spatial: a
    spatial one (masked LPIPS, `r360gpu.metrics.fidelity.masked_lpips` of its map); None leaves the
    metric not computed with the reason.  compat feeds the [0, 1] images to LPIPS unscaled, as the
    script does (it calls lpips without ``normalize``); default maps them to the network's [-1, 1].
    """
    _check_mode(mode)
    normalize = mode == "default"
    x = np.asarray(photo, dtype=np.float64)
    photo_moments = _moments(x)
    out = []
    for render, w in zip(renders, weights, strict=True):
        y, _ = _pair(render, x)
        rec = InpaintView(view, psnr=psnr_3dgs(y, x), ssim=float(np.mean(_ssim_map(y, x, photo_moments))))
        out.append(rec)
        if lpips is None:
            rec.reasons["lpips"] = NO_LPIPS
        else:
            rec.lpips = lpips.distance(y, x, normalize=normalize)
        if w is None:
            rec.reasons.update(masked_psnr=no_mask_reason, masked_ssim=no_mask_reason, masked_lpips=no_mask_reason)
            continue
        rec.mask_pixels = int(np.count_nonzero(w))
        if rec.mask_pixels == 0 and mode == "default":
            rec.reasons.update(masked_psnr=EMPTY_MASK, masked_ssim=EMPTY_MASK, masked_lpips=EMPTY_MASK)
            continue
        rec.masked_psnr = masked_psnr(y, x, w)
        rec.masked_ssim = masked_ssim(y, x, w)
        if lpips_spatial is None:
            rec.reasons["masked_lpips"] = NO_LPIPS_SPATIAL
        else:
            # The weights are already the mode's (script or binary), which masked_lpips' own threshold keeps.
            value = masked_lpips(lpips_spatial.distance_map(y, x, normalize=normalize), w)
            rec.masked_lpips = math.nan if value is None else value  # compat: the script's 0 / 0
    return out


@dataclass
class MetricMean:
    """A metric's mean over a scene's views: ``n`` views with a finite value in it, ``n_infinite``
    infinite values (left out in default mode, in the mean in compat mode), ``n_missing`` not computed."""

    mean: float | None
    n: int
    n_infinite: int = 0
    n_missing: int = 0
    reason: str | None = None

    def to_dict(self) -> dict:
        return {"mean": json_values.enc_float(self.mean), "n": self.n, "n_infinite": self.n_infinite,
                "n_missing": self.n_missing, "reason": self.reason}


def metric_mean(values: Sequence[float | None], reasons: Sequence[str | None], *, mode: str = "default"
                ) -> MetricMean:
    """Mean of one metric over views.  compat: ``np.mean`` of every computed value as the script prints it
    (NaN and inf included); default: of the finite values, with the infinite ones counted."""
    _check_mode(mode)
    got = [float(v) for v in values if v is not None]
    missing = len(values) - len(got)
    reason = next((r for v, r in zip(values, reasons) if v is None and r), None)
    n_inf = sum(math.isinf(v) for v in got)
    if not got:
        return MetricMean(None, 0, 0, missing, reason)
    if mode == "compat":
        return MetricMean(float(np.mean(got)), len(got), n_inf, missing, reason)
    finite = [v for v in got if math.isfinite(v)]
    if finite:
        return MetricMean(float(np.mean(finite)), len(finite), n_inf, missing, reason)
    # Every computed value infinite: +inf only when all agree in sign (identical images), else NaN.
    return MetricMean(float(np.mean(got)), 0, n_inf, missing, reason)


#: The metrics of a whole scene's image sets (not of a view), in table order, with whether higher is better.
SET_METRICS: tuple[tuple[str, bool], ...] = (("fid", False), ("kid_mean", False))
NO_INCEPTION = "no Inception model given (--inception-model)"


@dataclass
class InpaintScene:
    """One method in one scene: the per-view records and each metric's mean (``means[metric]``), and
    the set metrics FID and KID (``None`` when not computed, ``set_reason`` then says why) between
    the scene's photographs and the method's renders (``n_ref``, ``n_out`` images)."""

    scene: str
    method: str
    views: list[InpaintView]
    means: dict[str, MetricMean]
    masks: str | None = None
    fid: float | None = None
    kid_mean: float | None = None
    kid_std: float | None = None
    set_reason: str | None = NO_INCEPTION
    n_ref: int | None = None
    n_out: int | None = None

    def to_dict(self) -> dict:
        return {"scene": self.scene, "method": self.method, "n_views": len(self.views), "masks": self.masks,
                "means": {k: m.to_dict() for k, m in self.means.items()},
                "fid": json_values.enc_float(self.fid), "kid_mean": json_values.enc_float(self.kid_mean),
                "kid_std": json_values.enc_float(self.kid_std), "set_reason": self.set_reason,
                "n_ref": self.n_ref, "n_out": self.n_out,
                "views": [v.to_dict() for v in self.views]}


def summarise(scene: str, method: str, views: list[InpaintView], *, mode: str = "default",
              masks: str | None = None) -> InpaintScene:
    """An `InpaintScene` with the mean of every metric of `METRICS`."""
    means = {name: metric_mean([getattr(v, name) for v in views], [v.reasons.get(name) for v in views], mode=mode)
             for name, _ in METRICS}
    return InpaintScene(scene, method, views, means, masks)


def overall_means(scenes: Sequence[InpaintScene], method: str) -> dict[str, float | None]:
    """Per metric (`METRICS`, then `SET_METRICS`), the mean over scenes of the method's scene values
    (scene-macro; a scene without a value is left out); ``None`` when no scene has one."""
    out: dict[str, float | None] = {}
    for name, _ in METRICS + SET_METRICS:
        vals = [v for s in scenes if s.method == method
                and (v := (s.means[name].mean if name in s.means else getattr(s, name))) is not None]
        out[name] = float(np.mean(vals)) if vals else None
    return out
