"""A plain numpy model of AuraFusion360's evaluation script ``aura_eval.py`` (PSNR, SSIM, masked PSNR, masked SSIM),
step by step as its torch code runs, in float32: the reference r360gpu's inpainting metrics are tested
against (tests/test_inpainting_metrics.py, tests/test_inpaint_layouts.py) and timed against
(bench/inpaint_vs_script.py).  Written apart from r360gpu.metrics.inpainting on purpose: explicit
zero padding with ``np.pad`` and a 121-tap correlation loop instead of OpenCV, float32 throughout,
its own natural sort and its own ``to_tensor`` model.

The steps modelled (torch / torchvision semantics):
* ``to_tensor(PIL image)``: 8-bit modes -> float32 / 255, mode ``1`` -> 0/1, ``I;16`` -> int16 (wrapping),
  ``I`` -> int32, ``F`` -> float32, shape (C, H, W); the mask tensor then ``[:, :3]`` and ``m[m > 0.5] = 1``.
* ``psnr``: float32 mean of the squared difference, ``20 * log10(1 / sqrt(mse))``.
* ``masked_psnr``: ``mask.bool().repeat(1, 3, 1, 1)`` selects, float32 mean, ``inf`` when the mean is 0
  (where the script's ``.item()`` would then fail), NaN for an empty selection.
* ``ssim``: float32 Gaussian taps ``exp(-(x - 5)^2 / (2 * 1.5^2))`` normalised, the 11x11 window their outer
  product, ``conv2d(padding=5, groups=C)``, the map's mean.
* masked SSIM: ``ssim(img * mask, gt * mask)`` with the mask repeated over the three channels.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from PIL import Image

F32 = np.float32


def natsorted_paths(paths):
    def key(p):
        out = []
        for tok in re.findall(r"\d+|\D+", Path(p).name):
            out.append((0, int(tok), "") if tok.isdigit() else (1, 0, tok))
        return out
    return sorted(paths, key=key)


def to_tensor(im: Image.Image) -> np.ndarray:
    """torchvision.transforms.functional.to_tensor of a PIL image, as a numpy (C, H, W) array."""
    if im.mode == "I":
        a = np.array(im, np.int32)
    elif im.mode.startswith("I;16"):
        a = np.array(im, np.int16)
    elif im.mode == "F":
        a = np.array(im, np.float32)
    else:
        a = np.array(im, np.uint8)
        if im.mode == "1":
            a = (255 * a).astype(np.uint8)
    a = a.reshape(im.size[1], im.size[0], len(im.getbands())).transpose(2, 0, 1)
    if a.dtype == np.uint8:
        return a.astype(F32) / F32(255)
    return a


def read_rgb(path) -> np.ndarray:
    return to_tensor(Image.open(path).convert("RGB"))


def read_mask(path) -> np.ndarray:
    m = to_tensor(Image.open(path))[:3].copy()
    m[m > 0.5] = 1
    return m


def psnr(img: np.ndarray, gt: np.ndarray) -> float:
    mse = np.mean(((img - gt) ** 2).reshape(-1), dtype=F32)
    with np.errstate(divide="ignore"):
        return float(F32(20) * np.log10(F32(1) / np.sqrt(mse)))


def masked_psnr(img: np.ndarray, gt: np.ndarray, mask: np.ndarray) -> float:
    if mask.shape[0] != 1:
        raise IndexError("the mask selects 3 x C channels of a 3-channel image")
    sel = np.repeat(mask != 0, 3, axis=0)
    d = ((img - gt) ** 2)[sel]
    if d.size == 0:
        return math.nan
    mse = np.mean(d, dtype=F32)
    if mse == 0:
        return math.inf
    return float(F32(20) * np.log10(F32(1) / np.sqrt(mse)))


def _window() -> np.ndarray:
    g = np.array([math.exp(-(x - 5) ** 2 / float(2 * 1.5 ** 2)) for x in range(11)], dtype=F32)
    g = g / g.sum(dtype=F32)
    return np.outer(g, g).astype(F32)


def _conv(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """conv2d(x, w, padding=5, groups=C) for (C, H, W) float32: a correlation over zero-padded input."""
    c, h, wd = x.shape
    p = np.pad(x, ((0, 0), (5, 5), (5, 5)))
    out = np.zeros((c, h, wd), F32)
    for ky in range(11):
        for kx in range(11):
            out += w[ky, kx] * p[:, ky:ky + h, kx:kx + wd]
    return out


def _conv_separable(x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The same correlation as :func:`_conv`, as two 1-D passes (the window is an outer product): what a
    numpy port of the script would do to be fast (bench/inpaint_vs_script.py)."""
    from scipy.ndimage import correlate1d

    y = correlate1d(x, g, axis=1, mode="constant", cval=0.0)
    return correlate1d(y, g, axis=2, mode="constant", cval=0.0)


def ssim(img1: np.ndarray, img2: np.ndarray, *, separable: bool = False) -> float:
    w = _window()
    if separable:
        g = np.sqrt(np.diag(w)).astype(F32)  # the 1-D taps: w = outer(g, g)
        def conv(x, _):
            return _conv_separable(x, g)
    else:
        conv = _conv
    mu1, mu2 = conv(img1, w), conv(img2, w)
    mu1_sq, mu2_sq, mu1_mu2 = mu1 ** 2, mu2 ** 2, mu1 * mu2
    s1 = conv(img1 * img1, w) - mu1_sq
    s2 = conv(img2 * img2, w) - mu2_sq
    s12 = conv(img1 * img2, w) - mu1_mu2
    c1, c2 = F32(0.01 ** 2), F32(0.03 ** 2)
    m = ((2 * mu1_mu2 + c1) * (2 * s12 + c2)) / ((mu1_sq + mu2_sq + c1) * (s1 + s2 + c2))
    return float(np.mean(m, dtype=F32))


def masked_ssim(img: np.ndarray, gt: np.ndarray, mask: np.ndarray, *, separable: bool = False) -> float:
    m = np.repeat(mask, 3, axis=0).astype(F32)
    return ssim(img * m, gt * m, separable=separable)


def score_pair_lists(gt_paths, render_paths, mask_paths, *, separable: bool = False) -> dict[str, list[float]]:
    """The script's per-view lists for one scene and method."""
    if not (len(gt_paths) == len(mask_paths) == len(render_paths)):
        raise ValueError("counts differ (the script stops at a breakpoint)")
    out = {"psnr": [], "ssim": [], "masked_psnr": [], "masked_ssim": []}
    for g, r, m in zip(gt_paths, render_paths, mask_paths):
        gt, img, mask = read_rgb(g), read_rgb(r), read_mask(m)
        out["masked_psnr"].append(masked_psnr(img, gt, mask))
        out["masked_ssim"].append(masked_ssim(img, gt, mask, separable=separable))
        out["ssim"].append(ssim(img, gt, separable=separable))
        out["psnr"].append(psnr(img, gt))
    return out


def score_usid_scene(scene_dir, method_dir, mask_dir, *, separable: bool = False) -> dict[str, float]:
    """Per-scene means as the script prints them (np.mean of the per-view values)."""
    gts = natsorted_paths(Path(scene_dir, "test_images").glob("*jpg"))
    renders = natsorted_paths(Path(method_dir, "renders").glob("*png"))
    masks = natsorted_paths(Path(mask_dir).glob("*.png"))
    lists = score_pair_lists(gts, renders, masks, separable=separable)
    return {k: float(np.mean(v)) for k, v in lists.items()}
