"""Weight-free semantic probe: an appearance model of the target, learnt per
scene from the pre-removal renderings, as a stand-in for Grounded-SAM.

:class:`BuiltinAppearanceProbe` (probe name ``builtin-appearance``) reports
where a rendering still *looks like* the removed object.  It has no notion of
object categories: the category prompt is recorded as the label of every
instance but is not interpreted.  Its "prompt" is instead an appearance model
fitted once per scene with :meth:`BuiltinAppearanceProbe.fit` from the
pre-removal renderings I_pre and the target masks M:

Features (per pixel of the working image, see below): the CIE L*a*b* colour
(OpenCV's 8-bit Lab), quantised into ``colour_bins`` = (L, a, b) bins, and a
texture level: the standard deviation of L over a ``texture_window`` square,
quantised at ``texture_edges`` (8-bit L units).  A pixel's bin is the
combination of both, ``prod(colour_bins) * (len(texture_edges) + 1)`` bins
in all.

Fit: histograms over all pre images of the target pixels (M eroded by
``boundary_px`` working pixels, so that pixels mixing object and background
are left out) and of the background pixels (outside M dilated by
``boundary_px``).  Both are smoothed over neighbouring bins (Gaussian,
``hist_sigma`` colour bins and ``texture_sigma`` texture levels: texture is a
soft cue, so that a blurred residual of a textured object still matches it)
and normalised to distributions p_t and p_b; the background one is mixed
with ``background_floor`` of a uniform distribution so that colours never
seen outside the object get a finite ratio.  Bins
holding less than ``min_target_mass`` of the target distribution are set to
p_t = 0 (a colour seen on a handful of target pixels is noise, not the
object's look).  The fitted model is the per-bin posterior
P = p_t / (p_t + p_b) (equal priors; P >= r / (1 + r) <=> likelihood ratio
p_t / p_b >= r).

Predict, per view (the view's own target mask is never used; the model is
a position-free histogram pooled over the scene):

1. shrink the rendering (area averaging) so its long side is at most
   ``work_long_side`` pixels (the same working size as in the fit);
2. look up P per pixel (histogram back-projection), blur the P map with a
   Gaussian of ``blur_frac`` x working long side;
3. keep pixels with likelihood ratio >= ``ratio_threshold``, then a
   morphological opening (radius ``open_frac`` x long side) removes
   speckle and a closing (radius ``close_frac`` x long side) fills small holes;
4. 8-connected components are the instances; components smaller than
   ``min_area_frac`` of the image are dropped, at most ``max_instances`` of
   the largest are kept (ordered by area);
5. an instance's score is the mean unblurred P over its pixels, in [0, 1];
6. labels are brought back to the view's size by nearest neighbour, so
   boundaries are as coarse as the working image (3 px at 1920x1080).

An image of one colour that the target never shows gives no detection.

What it can and cannot detect: residuals that keep the object's colours --
leftover parts, floaters, smeared (blurred) remains.  It cannot detect
shape-only evidence (an object-shaped region recoloured to the background's
colours), misses semi-transparent remains whose colours lie between the
object's and the background's, does not know object categories (a different
object of the same colours is reported too, and revealed background that
happens to share the object's colours is a false positive), and can be
fooled by lighting changes that move colours across bins.  Because the model
is fitted on the pre renderings inside M, IoU on those same pre renderings
is in-sample and optimistic (IoU_pre, hence IoU_drop, read high); the
post-removal IoU (acc_seg) is the meaningful number.  It is weaker than a learned probe and exists so that the semantic
axis can be computed anywhere, with no weights.
"""
from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter

from r360gpu.errors import InputError
from r360gpu.probes.base import ProbeView, SemanticPrediction, SemanticProbe
from r360gpu.probes.builtin import as_rgb_uint8, label_masks, to_working, working_size

__all__ = [
    "SEMANTIC_LIMITATIONS",
    "AppearanceParams",
    "AppearanceModel",
    "appearance_bins",
    "fit_appearance",
    "BuiltinAppearanceProbe",
]

#: One-line limitation statement recorded in ``describe()``.
SEMANTIC_LIMITATIONS = (
    "colour/texture histogram of the target learnt from the pre renderings, not a detector: finds residuals "
    "that keep the object's look; blind to shape-only evidence and to residuals recoloured like the background; "
    "ignores the prompt's meaning"
)


def _check(ok: bool, problem: str) -> None:
    if not ok:
        raise InputError(f"appearance probe parameters: {problem}")


@dataclass(frozen=True)
class AppearanceParams:
    """Parameters of :class:`BuiltinAppearanceProbe` (all go into ``describe()``).

    Lengths marked "frac" are fractions of the working image's long side
    (areas: of its area); "px" lengths are working-image pixels.

    work_long_side: long side (px) of the working image (renderings are
        shrunk to it, never enlarged).
    colour_bins: (L, a, b) bin counts over OpenCV's 8-bit Lab.
    texture_edges: increasing bin edges of the local standard deviation of L
        (8-bit units).
    texture_window: side (px) of the square window of that deviation.
    hist_sigma: Gaussian smoothing of the histograms over colour bins (bins).
    texture_sigma: Gaussian smoothing over texture levels (levels); it makes
        texture a soft cue, so a blurred residual of a textured object still
        matches it.
    background_floor: weight of the uniform distribution mixed into p_b.
    min_target_mass: bins with p_t below this are never target-like.
    ratio_threshold: likelihood ratio p_t / p_b at or above which a pixel
        looks like the target.
    blur_frac: sigma of the Gaussian blur of the posterior map.
    open_frac, close_frac: radii of the opening and closing (0: skipped).
    boundary_px: erosion / dilation of M in the fit.
    min_area_frac: smallest instance kept, as a fraction of the image area.
    max_instances: at most this many instances per view (the largest).
    """

    work_long_side: int = 640
    colour_bins: tuple[int, int, int] = (8, 16, 16)
    texture_edges: tuple[float, ...] = (2.0, 5.0, 12.0)
    texture_window: int = 5
    hist_sigma: float = 0.75
    texture_sigma: float = 1.0
    background_floor: float = 0.02
    min_target_mass: float = 2e-4
    ratio_threshold: float = 4.0
    blur_frac: float = 0.003
    open_frac: float = 0.004
    close_frac: float = 0.008
    boundary_px: int = 2
    min_area_frac: float = 0.001
    max_instances: int = 20

    def __post_init__(self) -> None:
        bins = tuple(int(b) for b in self.colour_bins)
        _check(
            len(bins) == 3 and all(1 <= b <= 256 for b in bins),
            f"colour_bins must be 3 counts in 1..256, got {self.colour_bins}",
        )
        object.__setattr__(self, "colour_bins", bins)
        edges = tuple(float(e) for e in self.texture_edges)
        _check(all(b > a for a, b in zip(edges, edges[1:])), f"texture_edges must increase, got {self.texture_edges}")
        object.__setattr__(self, "texture_edges", edges)
        _check(int(self.work_long_side) >= 8, f"work_long_side must be >= 8, got {self.work_long_side}")
        _check(int(self.texture_window) >= 1, f"texture_window must be >= 1, got {self.texture_window}")
        _check(float(self.hist_sigma) >= 0, f"hist_sigma must be >= 0, got {self.hist_sigma}")
        _check(float(self.texture_sigma) >= 0, f"texture_sigma must be >= 0, got {self.texture_sigma}")
        _check(0 < float(self.background_floor) <= 1, f"background_floor must be in (0, 1], got {self.background_floor}")
        _check(0 <= float(self.min_target_mass) < 1, f"min_target_mass must be in [0, 1), got {self.min_target_mass}")
        _check(float(self.ratio_threshold) > 0, f"ratio_threshold must be > 0, got {self.ratio_threshold}")
        for name in ("blur_frac", "open_frac", "close_frac"):
            _check(0 <= float(getattr(self, name)) < 1, f"{name} must be in [0, 1), got {getattr(self, name)}")
        _check(int(self.boundary_px) >= 0, f"boundary_px must be >= 0, got {self.boundary_px}")
        _check(0 <= float(self.min_area_frac) < 1, f"min_area_frac must be in [0, 1), got {self.min_area_frac}")
        _check(int(self.max_instances) >= 1, f"max_instances must be >= 1, got {self.max_instances}")

    @property
    def bin_count(self) -> int:
        """Number of histogram bins: colour bins x texture levels."""
        return int(np.prod(self.colour_bins)) * (len(self.texture_edges) + 1)


def appearance_bins(work: np.ndarray, params: AppearanceParams) -> np.ndarray:
    """Histogram bin of every pixel of a uint8 RGB working image: int64 (h, w)
    in 0..params.bin_count-1 (colour bin major, texture level minor)."""
    lab = cv2.cvtColor(work, cv2.COLOR_RGB2Lab)
    n_l, n_a, n_b = params.colour_bins
    q = lab.astype(np.int64)
    colour = ((q[..., 0] * n_l >> 8) * n_a + (q[..., 1] * n_a >> 8)) * n_b + (q[..., 2] * n_b >> 8)
    lum = lab[..., 0].astype(np.float32)
    win = (int(params.texture_window),) * 2
    mean = cv2.boxFilter(lum, cv2.CV_32F, win, borderType=cv2.BORDER_REFLECT)
    mean_sq = cv2.boxFilter(lum * lum, cv2.CV_32F, win, borderType=cv2.BORDER_REFLECT)
    std = np.sqrt(np.maximum(mean_sq - mean * mean, 0.0))
    texture = np.digitize(std, np.asarray(params.texture_edges, np.float32))
    return colour * (len(params.texture_edges) + 1) + texture


@dataclass(frozen=True, eq=False)
class AppearanceModel:
    """A fitted appearance model (see the module docstring).

    posterior: float32 (params.bin_count,), P(target | bin) under equal priors.
    images: number of pre images fitted; target_pixels / background_pixels:
        working-resolution pixel counts that went into the two histograms.
    sha256: hex digest of the parameters and the posterior table, recorded in
        ``describe()`` so cached predictions of another fit never match.
    """

    params: AppearanceParams
    posterior: np.ndarray
    images: int
    target_pixels: int
    background_pixels: int
    sha256: str


def _as_mask(mask, what: str) -> np.ndarray:
    arr = np.asarray(mask)
    if arr.ndim != 2:
        raise InputError(f"{what}: mask must be (H, W), got shape {arr.shape}")
    if arr.dtype == bool:
        return arr
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"{what}: mask must be bool or integer (non-zero = target), got dtype {arr.dtype}")
    return arr != 0


def _working_mask(mask: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """bool (h, w) target mask at working size: pixels at least half covered,
    or every touched pixel when that leaves nothing of a non-empty mask."""
    h, w = size
    if mask.shape == (h, w):
        return mask
    cover = cv2.resize(mask.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    small = cover >= 0.5
    if not small.any() and mask.any():
        small = cover > 0
    return small


def _disk(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def fit_appearance(pre_images: Sequence, masks: Sequence, params: AppearanceParams | None = None) -> AppearanceModel:
    """Fit the target's appearance model from pre-removal renderings.

    pre_images: I_pre per view, each (H, W, 3) uint8 or float 0..1.
    masks: M per view, bool or integer (H, W) (non-zero = target), the same
        size as its image.  Views may differ in size.
    params: :class:`AppearanceParams` (defaults when None).

    Raises InputError when the lists differ in length or are empty, when an
    image or mask is malformed or their sizes differ, when no view has any
    target pixel (nothing to learn) or no view has any background pixel
    (nothing to contrast with).
    """
    params = AppearanceParams() if params is None else params
    pre_images, masks = list(pre_images), list(masks)
    if len(pre_images) != len(masks):
        raise InputError(f"appearance fit: {len(pre_images)} pre images but {len(masks)} masks")
    if not pre_images:
        raise InputError("appearance fit: no pre images given")
    n_bins = params.bin_count
    target_hist = np.zeros(n_bins, np.float64)
    background_hist = np.zeros(n_bins, np.float64)
    radius = int(params.boundary_px)
    for i, (image, mask) in enumerate(zip(pre_images, masks)):
        rgb = as_rgb_uint8(image, f"pre image {i}")
        target = _as_mask(mask, f"mask {i}")
        if target.shape != rgb.shape[:2]:
            raise InputError(
                f"mask {i} is {target.shape[1]}x{target.shape[0]} but pre image {i} is {rgb.shape[1]}x{rgb.shape[0]}"
            )
        size = working_size(rgb.shape[0], rgb.shape[1], int(params.work_long_side))
        bins = appearance_bins(to_working(rgb, size), params)
        small = _working_mask(target, size).astype(np.uint8)
        inner, outer = small.astype(bool), ~small.astype(bool)
        if radius > 0:
            eroded = cv2.erode(small, _disk(radius), borderType=cv2.BORDER_REPLICATE).astype(bool)
            # A mask thinner than the erosion would vanish: keep it whole then.
            inner = eroded if eroded.any() else inner
            outer = ~cv2.dilate(small, _disk(radius), borderType=cv2.BORDER_REPLICATE).astype(bool)
        target_hist += np.bincount(bins[inner], minlength=n_bins)
        background_hist += np.bincount(bins[outer], minlength=n_bins)
    n_target, n_background = int(target_hist.sum()), int(background_hist.sum())
    if n_target == 0:
        raise InputError("appearance fit: the masks have no target pixels, so the target's look cannot be learnt")
    if n_background == 0:
        raise InputError("appearance fit: the masks cover every pixel, so there is no background to contrast with")
    posterior = _posterior(target_hist, background_hist, params)
    digest = hashlib.sha256()
    digest.update(repr(sorted(asdict(params).items())).encode())
    digest.update(posterior.tobytes())
    return AppearanceModel(params, posterior, len(pre_images), n_target, n_background, digest.hexdigest())


def _smoothed(hist: np.ndarray, params: AppearanceParams) -> np.ndarray:
    shape = (*params.colour_bins, len(params.texture_edges) + 1)
    grid = hist.reshape(shape)
    if params.hist_sigma > 0:
        grid = gaussian_filter(grid, sigma=(params.hist_sigma,) * 3 + (params.texture_sigma,), mode="constant", truncate=3.0)
    grid = grid.reshape(-1)
    return grid / grid.sum()


def _posterior(target_hist: np.ndarray, background_hist: np.ndarray, params: AppearanceParams) -> np.ndarray:
    p_t = _smoothed(target_hist, params)
    p_t[p_t < params.min_target_mass] = 0.0
    floor = float(params.background_floor)
    p_b = (1.0 - floor) * _smoothed(background_hist, params) + floor / params.bin_count
    return (p_t / (p_t + p_b)).astype(np.float32)


class BuiltinAppearanceProbe(SemanticProbe):
    """Weight-free semantic probe: where a rendering still looks like the target (module docstring).

    params: `AppearanceParams` (defaults when None).  Call `fit`
    once per scene before `predict`.
    """

    learns_from_scene = True

    def __init__(self, params: AppearanceParams | None = None):
        self.config = AppearanceParams() if params is None else params
        self.model: AppearanceModel | None = None

    @property
    def name(self) -> str:
        return "builtin-appearance"

    def fit(self, pre_images: Sequence, masks: Sequence) -> "BuiltinAppearanceProbe":
        """Learn the scene's target appearance (`fit_appearance`); returns self."""
        self.model = fit_appearance(pre_images, masks, self.config)
        return self

    def params(self) -> dict:
        """The parameters plus ``model_sha256`` (None before `fit`)."""
        values = asdict(self.config)
        values["model_sha256"] = None if self.model is None else self.model.sha256
        return values

    def describe(self) -> dict:
        """Base description plus ``weight_free``, ``limitations``, ``prompt_use`` and
        the fit's pixel counts (``fit``: None before `fit`)."""
        out = super().describe()
        out["weight_free"] = True
        out["limitations"] = SEMANTIC_LIMITATIONS
        out["prompt_use"] = "recorded as every instance's label; not interpreted"
        model = self.model
        out["fit"] = None if model is None else {
            "images": model.images,
            "target_pixels": model.target_pixels,
            "background_pixels": model.background_pixels,
        }
        return out

    def posterior_map(self, image: np.ndarray, what: str = "image") -> np.ndarray:
        """float32 (h, w) unblurred P(target) of the working image of one RGB
        rendering ((H, W, 3) uint8 or float 0..1)."""
        model = self._fitted()
        rgb = as_rgb_uint8(image, what)
        work = to_working(rgb, working_size(rgb.shape[0], rgb.shape[1], int(self.config.work_long_side)))
        return model.posterior[appearance_bins(work, self.config)]

    def predict_image(self, image: np.ndarray, prompt: str, what: str = "image") -> SemanticPrediction:
        """Instances in one RGB rendering ((H, W, 3) uint8 or float 0..1):
        bool (K, H, W) masks, float32 (K,) scores, K labels equal to ``prompt``."""
        p = self.config
        rgb = as_rgb_uint8(image, what)
        size = rgb.shape[:2]
        prob = self.posterior_map(rgb, what)
        h, w = prob.shape
        long_side = max(h, w)
        sigma = p.blur_frac * long_side
        smooth = cv2.GaussianBlur(prob, (0, 0), sigma, borderType=cv2.BORDER_REFLECT) if sigma >= 0.3 else prob
        cut = p.ratio_threshold / (1.0 + p.ratio_threshold)
        fg = (smooth >= cut).astype(np.uint8)
        for op, frac in ((cv2.MORPH_OPEN, p.open_frac), (cv2.MORPH_CLOSE, p.close_frac)):
            radius = int(round(frac * long_side))
            if radius >= 1:
                fg = cv2.morphologyEx(fg, op, _disk(radius), borderType=cv2.BORDER_REPLICATE)
        n, labels, stats, _ = cv2.connectedComponentsWithStats(fg, connectivity=8, ltype=cv2.CV_32S)
        area = stats[1:, cv2.CC_STAT_AREA].astype(np.int64)
        ids = np.arange(1, n, dtype=np.int64)
        keep = area >= max(1.0, p.min_area_frac * h * w)
        ids, area = ids[keep], area[keep]
        # Component ids follow raster order of first pixel, which breaks area ties.
        ids = ids[np.lexsort((ids, -area))][: int(p.max_instances)]
        if ids.size:
            sums = np.bincount(labels.reshape(-1), weights=prob.reshape(-1).astype(np.float64), minlength=n)
            scores = (sums[ids] / stats[ids, cv2.CC_STAT_AREA]).astype(np.float32)
        else:
            scores = np.zeros(0, np.float32)
        masks = label_masks(labels, ids, size)
        return SemanticPrediction(masks, scores, [prompt] * int(ids.size), self.name)

    def predict(self, views: Sequence[ProbeView], prompt: str) -> list[SemanticPrediction]:
        """One prediction per view, at the view's size; every view needs its image."""
        self._fitted()
        out = []
        for view in views:
            if view.image is None:
                raise InputError(f"probe {self.name!r} needs the rendered image of view {view.name!r}, and none was given")
            out.append(self.predict_image(view.image, prompt, f"view {view.name!r}"))
        return out

    def _fitted(self) -> AppearanceModel:
        if self.model is None:
            raise RuntimeError("builtin-appearance: call fit(pre_images, masks) for the scene before predicting")
        return self.model
