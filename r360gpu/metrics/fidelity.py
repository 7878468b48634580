"""Pixel fidelity of I_post against I_ref: PSNR, SSIM, LPIPS (diagnostics only;
never in RQS or ranks; the paper's "Pixel fidelity vs I_ref").

Images are (H, W, 3) or (H, W) RGB / gray, either uint8 (0..255, divided by
255) or float in [0, 1]; values outside [0, 1] or non-finite values are an
input error (clipping is the renderer's decision, not this module's).

PSNR.  ``PSNR = 10 log10(1 / MSE)`` dB, MSE over all pixels and channels of
the [0, 1] images.  Identical images (MSE = 0) give ``+inf``.  Over views,
:func:`fidelity_summary` averages PSNR over the views with a finite value and
reports the number of identical views beside it (``psnr_n_identical``); the
mean is ``+inf`` only when every view is identical.  (Averaging an inf in would
hide every other view; capping it at an arbitrary dB value would invent a
number.)

SSIM (Wang et al., IEEE TIP 2004).  11 x 11 Gaussian window, sigma = 1.5
(normalised to sum 1), ``C1 = (0.01 L)^2``, ``C2 = (0.03 L)^2`` with data range
L = 1, population (biased) local variances and covariance.  Border handling:
the SSIM map is evaluated only where the window lies entirely inside the image
(the "valid" region, (H - 10) x (W - 10) positions), and the mean is taken over
those positions and over channels.  This equals Wang et al.'s MATLAB
``ssim_index`` (``filter2(..., 'valid')``, without its optional downsampling)
and ``skimage.metrics.structural_similarity(..., gaussian_weights=True,
sigma=1.5, use_sample_covariance=False, data_range=1, channel_axis=-1)``, which
filters with reflect padding and then crops the 5-pixel border, so the
padding never enters the mean.  Images smaller than 11 pixels in either
dimension are an input error.  :func:`ssim` and :func:`ssim_map` compute it in
float64 (OpenCV separable filters); the per-view records
(:func:`fidelity_view`, :func:`fidelity_views`) use the batched kernels of
:mod:`r360gpu.kernels.ssim`, within ``SSIM_TOL`` of the same definition
(tests/test_kernel_ssim.py), and measure all methods of a view against I_ref
in one call.

LPIPS.  Computed only with an LPIPS network exported to ONNX
(:class:`LpipsModel`; AlexNet or VGG variant): two float32 NCHW inputs in
[-1, 1] (their names are read from the model, in the model's order) and one
output holding the distance.  The model file's name and SHA-256 go into the
result.  Without a model LPIPS is *not computed*: ``lpips = None`` with a
reason, never 0.  An export of ``lpips.LPIPS(spatial=True)`` outputs the
distance map ``(N, 1, H, W)`` instead (each layer's map upsampled bilinearly to
the image and summed): `LpipsModel.distance_map` reads it, and
`masked_lpips` weights it by an object mask as the 360-USID script
(AuraFusion360's ``aura_eval.py``) does.  The map's mean is not the plain
export's distance (the upsampling does not preserve means), so each export is
refused where the other is needed.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import InputError
from ..kernels.ssim import image_hwc, ssim_mse_many
from ..util.filehash import file_sha256
from . import json_values

SSIM_WIN = 11
SSIM_SIGMA = 1.5
SSIM_K1 = 0.01
SSIM_K2 = 0.03

#: Reason recorded when no LPIPS model is given.
NO_LPIPS_MODEL = "no LPIPS model given"


def as_image(img, what: str = "image") -> np.ndarray:
    """float64 (H, W, C) in [0, 1] from uint8 or float (H, W[, C]) input."""
    a = image_hwc(img, what)
    if a.dtype == np.uint8:
        return a.astype(np.float64) / 255.0
    if not np.issubdtype(a.dtype, np.floating):
        raise InputError(f"{what} must be uint8 or float in [0, 1], got dtype {a.dtype}")
    out = a.astype(np.float64)
    if not np.isfinite(out).all():
        raise InputError(f"{what} contains NaN or infinite values")
    lo, hi = float(out.min()), float(out.max())
    if lo < 0.0 or hi > 1.0:
        raise InputError(f"{what} has values in [{lo:.6g}, {hi:.6g}], outside [0, 1]")
    return out


def _pair(a, b) -> tuple[np.ndarray, np.ndarray]:
    x = as_image(a, "I_post")
    y = as_image(b, "I_ref")
    if x.shape != y.shape:
        raise InputError(f"I_post is {x.shape} but I_ref is {y.shape} (H, W, C)")
    return x, y


def mse(a, b) -> float:
    """Mean squared error over pixels and channels of two [0, 1] images."""
    x, y = _pair(a, b)
    return float(np.mean((x - y) ** 2))


def psnr_from_mse(err: float) -> float:
    """10 log10(1 / MSE) dB; +inf for MSE = 0."""
    return math.inf if err == 0.0 else float(10.0 * math.log10(1.0 / err))


def psnr(a, b) -> float:
    """PSNR (dB) of two images on [0, 1] (+inf when identical)."""
    return psnr_from_mse(mse(a, b))


def gaussian_window(size: int = SSIM_WIN, sigma: float = SSIM_SIGMA) -> np.ndarray:
    """(size,) float64 1-D Gaussian taps summing to 1 (the 2-D window is the outer product)."""
    x = np.arange(size, dtype=np.float64) - (size - 1) / 2.0
    g = np.exp(-(x * x) / (2.0 * sigma * sigma))
    return g / g.sum()


def _filter_valid(img: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Separable correlation of (H, W, C) with g x g, valid region only (float64).

    OpenCV filters the whole image (its border values are cropped away, so the
    border mode never matters); output (y, x) is the window starting at
    (y, x), as in the plain definition sum_k g[k] img[y + k].
    """
    n = len(g)
    h, w = img.shape[:2]
    r = n // 2
    full = cv2.sepFilter2D(np.ascontiguousarray(img, np.float64), cv2.CV_64F, g, g, borderType=cv2.BORDER_REFLECT)
    if full.ndim == 2:
        full = full[:, :, None]
    return full[r : h - (n - 1 - r), r : w - (n - 1 - r)]


def ssim_map(a, b) -> np.ndarray:
    """SSIM map (H - 10, W - 10, C) float64 of two [0, 1] images (valid region)."""
    x, y = _pair(a, b)
    if x.shape[0] < SSIM_WIN or x.shape[1] < SSIM_WIN:
        raise InputError(f"SSIM needs images of at least {SSIM_WIN}x{SSIM_WIN} pixels, got {x.shape[0]}x{x.shape[1]}")
    g = gaussian_window()
    c1 = (SSIM_K1 * 1.0) ** 2
    c2 = (SSIM_K2 * 1.0) ** 2
    # Same formula as Wang et al.; in-place steps keep 1080p frames cheap.
    mx, my = _filter_valid(x, g), _filter_valid(y, g)
    mxy = mx * my
    mx *= mx  # mx^2
    my *= my  # my^2
    sxy = _filter_valid(x * y, g)
    sxy -= mxy
    den_s = _filter_valid(x * x, g)
    den_s += _filter_valid(y * y, g)
    den_s -= mx
    den_s -= my
    den_s += c2  # sxx + syy + c2
    num = mxy
    num *= 2.0
    num += c1
    sxy *= 2.0
    sxy += c2
    num *= sxy  # (2 mx my + c1)(2 sxy + c2)
    mx += my
    mx += c1
    mx *= den_s  # (mx^2 + my^2 + c1)(sxx + syy + c2)
    num /= mx
    return num


def ssim(a, b) -> float:
    """Mean SSIM over the valid region and the channels (see the module docstring)."""
    return float(np.mean(ssim_map(a, b)))


class LpipsModel:
    """An LPIPS network in ONNX form, run with onnxruntime.

    path: the .onnx file.  The model must have exactly two inputs of rank 4
    (N, 3, H, W) (names and order read from the model) and at least one
    output; its first output holds one value per image pair (the plain
    export) or a distance map (N, 1, H, W) per pair (the spatial export).
    device: the execution provider, chosen as the learned probes'
    (``--probe-device``, `r360gpu.probes.providers`); the one that ran is
    in `describe`.

    `spatial` is True for a map, False for one value, None while the
    declared output shape leaves it open (symbolic H, W): the first run decides.
    """

    def __init__(self, path: str | os.PathLike, device: str = "cpu"):
        import onnxruntime as ort

        from ..probes.providers import open_session, plan, started

        self.path = os.fspath(path)
        if not os.path.isfile(self.path):
            raise InputError("LPIPS model file not found", self.path)
        chosen = plan(device)
        self.sha256 = file_sha256(self.path)
        opts = ort.SessionOptions()
        opts.log_severity_level = 3
        try:
            self._session = open_session(self.path, opts, chosen)
        except Exception as exc:  # onnxruntime raises its own exception types
            raise InputError(f"not a loadable ONNX model ({type(exc).__name__}: {exc})", self.path) from None
        self.provider = started(self._session, chosen, self.path, "LPIPS model")
        inputs = self._session.get_inputs()
        if len(inputs) != 2:
            raise InputError(f"an LPIPS model needs two image inputs, this one has {len(inputs)}", self.path)
        for i in inputs:
            if len(i.shape) != 4:
                raise InputError(f"LPIPS input {i.name!r} has shape {i.shape}, expected (N, 3, H, W)", self.path)
            if isinstance(i.shape[1], int) and i.shape[1] != 3:
                raise InputError(f"LPIPS input {i.name!r} has {i.shape[1]} channels, expected 3", self.path)
        self.input_names = tuple(i.name for i in inputs)
        self._input_shapes = tuple(tuple(i.shape) for i in inputs)
        out = self._session.get_outputs()[0]
        self.output_name = out.name
        self.spatial = _declared_spatial(tuple(out.shape))

    @property
    def file_name(self) -> str:
        return os.path.basename(self.path)

    def describe(self) -> dict:
        """{"file", "sha256", "inputs", "output", "provider"} for the results."""
        return {
            "file": self.file_name,
            "sha256": self.sha256,
            "inputs": list(self.input_names),
            "output": self.output_name,
            "provider": self.provider,
        }

    def distance(self, a, b, *, normalize: bool = True) -> float:
        """LPIPS distance between two images ((H, W, 3) uint8 or [0, 1] float).

        normalize: as ``lpips.LPIPS.forward``'s flag: True maps the [0, 1] images to
        the network's [-1, 1]; False feeds them unchanged, as the 360-USID script does
        (it passes ``to_tensor`` images without the flag).  A spatial export is refused.
        """
        if self.spatial:
            self._wrong_kind(True)
        out, (h, w) = self._forward(a, b, normalize)
        if self._is_map(out, h, w):
            self._wrong_kind(True)
        value = float(np.asarray(out, np.float64).ravel()[0])
        if not np.isfinite(value):
            raise InputError(f"LPIPS output is not finite ({value})", self.path)
        return value

    def distance_map(self, a, b, *, normalize: bool = True) -> np.ndarray:
        """(H, W) float64 LPIPS distance map of a spatial export (``lpips.LPIPS(spatial=True)``).

        normalize: as in `distance`.  A plain (one-distance) export is refused.
        """
        if self.spatial is False:
            self._wrong_kind(False)
        out, (h, w) = self._forward(a, b, normalize)
        if not self._is_map(out, h, w):
            self._wrong_kind(False)
        lmap = np.asarray(out, np.float64).reshape(h, w)
        if not np.isfinite(lmap).all():
            raise InputError("LPIPS map has non-finite values", self.path)
        return lmap

    def require(self, spatial: bool, size: tuple[int, int]) -> None:
        """InputError naming the file unless this is the kind of export asked for (spatial: a distance
        map; else one distance), checked before any work: from the declared output shape, or when that
        leaves it open by one run on a black pair of ``size`` (H, W), the images it will be given."""
        if self.spatial is None:
            blank = np.zeros((*size, 3))
            self._is_map(self._forward(blank, blank, True)[0], *size)
        if self.spatial != spatial:
            self._wrong_kind(bool(self.spatial))

    def _wrong_kind(self, spatial: bool):
        if spatial:
            raise InputError(
                "a spatial LPIPS export (its output is a distance map): the whole-image LPIPS needs the "
                "plain export (lpips.LPIPS(spatial=False)); the map's mean is not that distance",
                self.path,
            )
        raise InputError(
            "gives one LPIPS distance per image pair, not a map: masked LPIPS needs the spatial export "
            "(lpips.LPIPS(spatial=True))",
            self.path,
        )

    def _is_map(self, out: np.ndarray, h: int, w: int) -> bool:
        """Whether a run's output is a distance map (and so this model spatial), checking its size."""
        n = int(np.asarray(out).size)
        if n == 1 and h * w > 1:
            spatial = False
        elif n == h * w:
            spatial = True
        else:
            raise InputError(
                f"LPIPS output {self.output_name!r} has shape {tuple(np.shape(out))} for {h}x{w} images; "
                f"expected one distance or a (1, 1, {h}, {w}) map",
                self.path,
            )
        if self.spatial is None:
            self.spatial = spatial
        return spatial

    def _forward(self, a, b, normalize: bool) -> tuple[np.ndarray, tuple[int, int]]:
        x, y = _pair(a, b)
        h, w = x.shape[:2]
        for name, shape in zip(self.input_names, self._input_shapes):
            for dim, size in ((2, h), (3, w)):
                if isinstance(shape[dim], int) and shape[dim] != size:
                    raise InputError(
                        f"LPIPS input {name!r} has a fixed shape {shape}, the images are {h}x{w}", self.path
                    )
        feeds = {n: _to_nchw(im, normalize) for n, im in zip(self.input_names, (x, y))}
        try:
            out = self._session.run([self.output_name], feeds)[0]
        except Exception as exc:
            raise InputError(f"LPIPS model failed on {h}x{w} images ({type(exc).__name__}: {exc})", self.path) from None
        return out, (h, w)


def _declared_spatial(shape: tuple) -> bool | None:
    """From an LPIPS export's declared output shape: a map (True), one distance (False), or open (None)."""
    if len(shape) < 4:
        return False if all(isinstance(d, int) for d in shape) else None
    hw = shape[-2:]
    if all(isinstance(d, int) for d in hw):
        return hw != (1, 1)
    return True if any(isinstance(d, int) and d > 1 for d in hw) else None


def script_mask_weights(mask) -> np.ndarray:
    """(H, W, C) float64 pixel weights of an object mask, as the 360-USID script makes them.

    ``aura_eval.py`` reads the mask PNG with ``to_tensor`` (uint8 / 255), keeps up to 3
    channels, then sets values above 0.5 to 1: values in (0, 0.5] keep their fraction.
    mask: (H, W) or (H, W, C) with C <= 3 (the channels ``to_tensor`` gives the PNG), uint8,
    bool (0 / 1) or float in [0, 1].
    """
    m = np.asarray(mask)
    if m.ndim == 2:
        m = m[:, :, None]
    if m.ndim != 3 or not 1 <= m.shape[2] <= 3:
        raise InputError(f"object mask must be (H, W) or (H, W, C <= 3), got shape {m.shape}")
    if m.dtype == np.uint8:
        w = m.astype(np.float64) / 255.0
    elif m.dtype == np.bool_:
        w = m.astype(np.float64)
    elif m.dtype.kind == "f":
        w = m.astype(np.float64)
        if not np.isfinite(w).all() or w.min() < 0.0 or w.max() > 1.0:
            raise InputError("object mask has values outside [0, 1] or non-finite values")
    else:
        raise InputError(f"object mask must be uint8, bool or float in [0, 1], got {m.dtype}")
    w[w > 0.5] = 1.0
    return w


def masked_lpips(lpips_map, mask) -> float | None:
    """LPIPS inside an object mask: ``sum(map * w) / sum(w)`` with the 360-USID script's weights.

    lpips_map: (H, W) (or (1, 1, H, W)) from `LpipsModel.distance_map`; mask: as
    `script_mask_weights` takes it.  A multi-channel mask weights each pixel by the sum
    of its channels' weights (the script's broadcast of the 1-channel map over the mask's
    channels).  An empty mask (no weight) gives None: the script's 0 / 0 is NaN, which
    makes its per-scene mean NaN; the caller reports the view as excluded.
    """
    lmap = np.asarray(lpips_map, np.float64)
    if lmap.ndim > 2 and all(d == 1 for d in lmap.shape[:-2]):
        lmap = lmap.reshape(lmap.shape[-2:])
    w = script_mask_weights(mask)
    if lmap.ndim != 2 or lmap.shape != w.shape[:2]:
        raise InputError(f"LPIPS map is {np.shape(lpips_map)}, the object mask {np.shape(mask)}: sizes differ")
    total = float(w.sum())
    if total == 0.0:
        return None
    return float(np.sum(lmap[:, :, None] * w) / total)


def _to_nchw(img: np.ndarray, normalize: bool = True) -> np.ndarray:
    """(H, W, C) [0, 1] -> float32 (1, 3, H, W), in [-1, 1] when ``normalize`` (gray repeated to 3 channels)."""
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    if normalize:
        img = img * 2.0 - 1.0
    return np.ascontiguousarray(img.transpose(2, 0, 1)[None].astype(np.float32))


@dataclass(frozen=True)
class FidelityView:
    """Fidelity of I_post against I_ref on one view.

    mse: mean squared error on [0, 1]; psnr: dB (+inf when identical);
    ssim: mean SSIM (valid region); lpips: the distance, or None when not
    computed, with ``lpips_reason`` saying why; lpips_model: {"file",
    "sha256", ...} of the model used (None when not computed).
    """

    mse: float
    psnr: float
    ssim: float
    lpips: float | None
    lpips_reason: str | None
    lpips_model: dict | None

    def to_dict(self) -> dict:
        return {
            "mse": self.mse,
            "psnr": json_values.enc_float(self.psnr),
            "ssim": self.ssim,
            "lpips": self.lpips,
            "lpips_reason": self.lpips_reason,
            "lpips_model": None if self.lpips_model is None else dict(self.lpips_model),
        }

    @classmethod
    def from_dict(cls, d: dict) -> "FidelityView":
        what = "fidelity view record"
        f = lambda k: json_values.field(d, k, what)  # noqa: E731
        lp = f("lpips")
        return cls(
            mse=json_values.dec_float(f("mse"), what),
            psnr=json_values.dec_float(f("psnr"), what),
            ssim=json_values.dec_float(f("ssim"), what),
            lpips=None if lp is None else json_values.dec_float(lp, what),
            lpips_reason=f("lpips_reason"),
            lpips_model=None if f("lpips_model") is None else dict(f("lpips_model")),
        )


def _same_kind(posts: Sequence, ref) -> tuple[list, object]:
    """All uint8, or all float32 (uint8 ones scaled to [0, 1]) when the kinds are mixed."""
    arrs = [np.asarray(p) for p in posts]
    r = np.asarray(ref)
    kinds = {a.dtype == np.uint8 for a in (*arrs, r)}
    if len(kinds) == 1:
        return arrs, r
    conv = lambda a: a.astype(np.float32) / np.float32(255.0) if a.dtype == np.uint8 else a  # noqa: E731
    return [conv(a) for a in arrs], conv(r)


def fidelity_views(posts: Sequence, ref, lpips_model: LpipsModel | None = None, *, ctx=None,
                   what: Sequence[str] | None = None) -> list[FidelityView]:
    """PSNR, SSIM and (with a model) LPIPS of every I_post of ``posts`` (e.g. the
    methods of one view) against one I_ref; I_ref is prepared once.

    what: names of the posts for error messages (default "I_post").
    """
    names = list(what) if what is not None else ["I_post"] * len(posts)
    arrs, r = _same_kind(posts, ref)
    stats = ssim_mse_many(arrs, r, ctx=ctx, what=names)
    out = []
    for a, (s, err) in zip(arrs, stats):
        if lpips_model is None:
            lp, reason, desc = None, NO_LPIPS_MODEL, None
        else:
            lp, reason, desc = lpips_model.distance(a, r), None, lpips_model.describe()
        out.append(FidelityView(err, psnr_from_mse(err), s, lp, reason, desc))
    return out


def fidelity_view(post, ref, lpips_model: LpipsModel | None = None, *, ctx=None) -> FidelityView:
    """PSNR, SSIM and (with a model) LPIPS of I_post against I_ref."""
    return fidelity_views([post], ref, lpips_model, ctx=ctx)[0]


@dataclass(frozen=True)
class FidelitySummary:
    """Fidelity over views.

    psnr: mean over the views with finite PSNR (+inf if all are identical,
        None for no views); psnr_n_identical: views with PSNR = +inf.
    ssim: mean SSIM (None for no views).
    lpips: mean over the views where it was computed; None, with
        ``lpips_reason``, when it was not computed for every view.
    """

    n_views: int
    psnr: float | None
    psnr_n_identical: int
    ssim: float | None
    lpips: float | None
    lpips_reason: str | None

    def to_dict(self) -> dict:
        return {
            "n_views": self.n_views,
            "psnr": json_values.enc_float(self.psnr),
            "psnr_n_identical": self.psnr_n_identical,
            "ssim": self.ssim,
            "lpips": self.lpips,
            "lpips_reason": self.lpips_reason,
        }


def fidelity_summary(views: Sequence[FidelityView]) -> FidelitySummary:
    """Means over views (see the module docstring for PSNR's +inf)."""
    n = len(views)
    finite = [v.psnr for v in views if math.isfinite(v.psnr)]
    n_ident = n - len(finite)
    if finite:
        ps = float(np.mean(finite))
    else:
        ps = math.inf if n else None
    ss = float(np.mean([v.ssim for v in views])) if n else None
    missing = [v for v in views if v.lpips is None]
    if not n:
        lp, reason = None, "no views"
    elif missing:
        reasons = sorted({v.lpips_reason or "not computed" for v in missing})
        lp, reason = None, f"not computed for {len(missing)} of {n} views: " + "; ".join(reasons)
    else:
        lp, reason = float(np.mean([v.lpips for v in views])), None
    return FidelitySummary(n, ps, n_ident, ss, lp, reason)
