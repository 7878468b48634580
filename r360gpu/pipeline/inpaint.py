"""Scoring the inpainting benchmarks' folders (360-USID, SPIn-NeRF) and their results document.

`score_scenes` reads every scene's photographs, each method's renders and the object
masks (`r360gpu.io.inpaint_folders`), scores every view (`r360gpu.metrics.inpainting`)
and summarises each (scene, method).  `results_document` is the ``results.json`` of the
``inpaint`` command (schema `r360gpu.protocol.INPAINT_SCHEMA`); its top-level keys::

    schema, r360gpu_version, created, protocol, mode, differs_from_script, inputs, methods,
    scenes   {SCENE: {METHOD: {scene, method, n_views, masks, means {METRIC: {mean, n, n_infinite,
             n_missing, reason}}, fid, kid_mean, kid_std, set_reason, n_ref, n_out,
             views [{view, psnr, ssim, masked_psnr, masked_ssim, lpips, masked_lpips, mask_pixels,
             reasons}]}}},
    overall  {METHOD: {METRIC: mean over scenes}},
    warnings

Non-finite values are written as ``{"__float__": "inf"}`` (`r360gpu.metrics.json_values`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.inpaint_folders import MethodFiles, SceneFiles, read_image, read_mask_binary, read_mask_script
from ..metrics import json_values
from ..metrics.fid import fid_from_features, fid_image_files, kid_from_features
from ..metrics.inpainting import (METRICS, MODES, SET_METRICS, InpaintScene, overall_means, score_views,
                                  script_weights, summarise)
from ..protocol import INPAINT_SCHEMA
from ..util.progress import progress
from ..util.warning_log import warn, where

#: The benchmarks the ``inpaint`` command scores, with the name tables show.
PROTOCOLS = {"360usid": "360-USID (AuraFusion360)", "spinnerf": "SPIn-NeRF"}

#: Where default mode departs from the benchmark's script, and why (results.json ``differs_from_script``).
DEFAULT_DIFFERENCES = (
    "object masks are binary, any non-zero pixel inside (the script keeps mask values in (0, 0.5] as "
    "fractional weights of masked SSIM, so an anti-aliased edge weighs less); 3-channel masks are read "
    "(the script fails on them)",
    "a view with an empty object mask has no masked PSNR, masked SSIM or masked LPIPS (the script gives NaN, "
    "a perfect 1 and NaN); its scene mean is over the other views",
    "scene means leave out infinite PSNRs (images identical over the measured pixels) and count them "
    "in n_infinite (the script's mean becomes inf, and its masked PSNR fails with an AttributeError)",
    "images with more than 8 bits per sample are read at full depth (the script clips them to 8 bits)",
    "LPIPS and masked LPIPS feed the networks the images mapped to [-1, 1], as LPIPS is defined "
    "(lpips(..., normalize=True)); the script passes the [0, 1] images unscaled, so its LPIPS values differ",
)
COMPAT_NOTE = ("compat mode: the script's definitions and mask weights; values equal its float32 numbers "
               "to 1e-4 (computed here in float64)")


@dataclass
class InpaintRun:
    protocol: str
    mode: str
    scenes: list[SceneFiles]
    results: list[InpaintScene]
    seconds: float

    @property
    def methods(self) -> list[str]:
        return [m.name for m in self.scenes[0].methods] if self.scenes else []


def _size_check(img: np.ndarray, shape: tuple[int, int], path: Path, photo: Path) -> None:
    if img.shape[:2] != shape:
        raise InputError(f"image is {img.shape[1]}x{img.shape[0]} but the photograph {photo} is "
                         f"{shape[1]}x{shape[0]}", path)


def _weights(path: Path, shape: tuple[int, int], mode: str) -> np.ndarray:
    if mode == "default":
        return read_mask_binary(path, shape)
    values = read_mask_script(path)
    if values.shape != shape:
        raise InputError(f"mask is {values.shape[1]}x{values.shape[0]} but the photograph is "
                         f"{shape[1]}x{shape[0]}", path)
    top = float(values.max()) if values.size else 0.0
    if 0.0 < top <= 0.5:
        # SPIn-NeRF's labels are 0/1 PNGs: to_tensor makes them 1/255, under the script's 0.5 threshold.
        warn(f"every mask value is at most {top:.4g} after the script's division by 255 (a 0/1 mask?): its masked "
             f"SSIM weighs the object by that value; default mode reads any non-zero pixel as the object", file=path)
    return script_weights(values)


def score_scenes(scenes: list[SceneFiles], *, protocol: str, mode: str = "default", show_progress: bool = True,
                 lpips=None, lpips_spatial=None, inception=None) -> InpaintRun:
    """Score every view of every scene and method; an unreadable or mismatched file is an InputError
    naming it, raised before anything is written.

    lpips, lpips_spatial: `r360gpu.metrics.fidelity.LpipsModel` plain and spatial exports (LPIPS,
    masked LPIPS; `r360gpu.metrics.inpainting.score_views`); inception: an
    `r360gpu.probes.inception.InceptionModel` (per-scene FID and KID, `fid_image_sets`).  A model
    not given leaves its metrics not computed, with the reason."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    t0 = time.perf_counter()
    results: list[InpaintScene] = []
    for scene in scenes:
        per_method: dict[str, list] = {m.name: [] for m in scene.methods}
        items = progress(list(enumerate(scene.photos)), desc=f"{scene.name}", enabled=show_progress)
        for i, photo_path in items:
            with where(scene=scene.name, view=photo_path.name):
                photo = read_image(photo_path, compat=mode == "compat")
                shape = photo.shape[:2]
                masks_read: dict[Path, np.ndarray] = {}
                renders, weights = [], []
                for m in scene.methods:
                    with where(method=m.name):
                        renders.append(read_image(m.renders[i], compat=mode == "compat"))
                        _size_check(renders[-1], shape, m.renders[i], photo_path)
                        if m.masks is not None and m.masks[i] not in masks_read:
                            masks_read[m.masks[i]] = _weights(m.masks[i], shape, mode)
                        weights.append(None if m.masks is None else masks_read[m.masks[i]])
                recs = score_views(photo_path.name, photo, renders, weights, mode=mode, lpips=lpips,
                                   lpips_spatial=lpips_spatial)
                for m, rec in zip(scene.methods, recs):
                    with where(method=m.name):
                        _warn_view(rec, mode, m.masks[i] if m.masks is not None else None)
                    per_method[m.name].append(rec)
        ref_features = None
        for m in scene.methods:
            results.append(summarise(scene.name, m.name, per_method[m.name], mode=mode,
                                     masks=None if m.mask_folder is None else str(m.mask_folder)))
            if inception is not None:
                with where(scene=scene.name, method=m.name):
                    ref_files, out_files = fid_image_sets(protocol, scene, m)
                    if ref_features is None:
                        ref_features = _features(inception, ref_files, mode)
                    _set_metrics(results[-1], ref_features, _features(inception, out_files, mode))
    _warn_mixed_masks(scenes)
    return InpaintRun(protocol, mode, scenes, results, time.perf_counter() - t0)


def fid_image_sets(protocol: str, scene: SceneFiles, method: MethodFiles) -> tuple[list[Path], list[Path]]:
    """The two image sets FID and KID compare for a scene and method: for 360-USID every image
    pytorch-fid reads in the photographs' folder and in the renders' folder, as the script's
    ``calculate_fid_given_paths`` on the two folders (all of their files, not only the matched views);
    for SPIn-NeRF, whose ``images/`` also holds the training photographs with the object, the
    scored test photographs and the method's renders of them."""
    if protocol == "360usid":
        return fid_image_files(scene.photos[0].parent), fid_image_files(method.renders[0].parent)
    return list(scene.photos), list(method.renders)


def _features(inception, files: list[Path], mode: str) -> np.ndarray:
    return inception.features(read_image(p, compat=mode == "compat") for p in files) if len(files) >= 2 else None


def _set_metrics(rec: InpaintScene, ref: np.ndarray | None, out: np.ndarray | None) -> None:
    if ref is None or out is None:
        rec.set_reason = "FID and KID need at least 2 images in each set"
        return
    fid = fid_from_features(ref, out, what=f"scene {rec.scene}, method {rec.method}")
    kid = kid_from_features(ref, out)
    rec.fid, rec.kid_mean, rec.kid_std = fid.value, kid.mean, kid.std
    rec.set_reason = fid.reason
    rec.n_ref, rec.n_out = len(ref), len(out)


def _warn_view(rec, mode: str, mask: Path | None) -> None:
    if rec.mask_pixels == 0:
        warn("empty object mask: " + ("no masked metrics at this view" if mode == "default" else
                                       "masked PSNR is NaN and masked SSIM 1, as the script computes them"),
             file=mask)
    elif mode == "compat" and rec.masked_psnr is not None and rec.masked_psnr == float("inf"):
        warn("render equals the photograph inside the mask: masked PSNR is inf; the script fails at this "
             "view (its masked_psnr returns a Python float, whose .item() raises AttributeError)", file=mask)


def _warn_mixed_masks(scenes: list[SceneFiles]) -> None:
    for s in scenes:
        folders = {str(m.mask_folder) for m in s.methods}
        if len(folders) > 1:
            warn(f"scene {s.name}: the methods' masked metrics use different mask folders ({', '.join(sorted(folders))}); "
                 f"give --masks to score every method on the same masks", scene=s.name)


def results_document(run: InpaintRun, inputs: dict, warnings: list[dict]) -> dict:
    """results.json of an ``inpaint`` run (see the module docstring)."""
    scenes: dict[str, dict] = {}
    for r in run.results:
        scenes.setdefault(r.scene, {})[r.method] = r.to_dict()
    return {
        "schema": INPAINT_SCHEMA,
        "r360gpu_version": __version__,
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "protocol": run.protocol,
        "protocol_name": PROTOCOLS[run.protocol],
        "mode": run.mode,
        "differs_from_script": list(DEFAULT_DIFFERENCES) if run.mode == "default" else [],
        "mode_note": COMPAT_NOTE if run.mode == "compat" else "default mode (see differs_from_script)",
        "metrics": [name for name, _ in METRICS],
        "set_metrics": [name for name, _ in SET_METRICS] + ["kid_std"],
        "inputs": inputs,
        "methods": run.methods,
        "scenes": scenes,
        "overall": {m: json_values.enc_tree(overall_means(run.results, m)) for m in run.methods},
        "warnings": warnings,
    }
