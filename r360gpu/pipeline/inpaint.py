"""Scoring the inpainting benchmarks' folders (360-USID, SPIn-NeRF) and their results document.

`score_scenes` reads every scene's photographs, each method's renders and the object
masks (`r360gpu.io.inpaint_folders`), scores every view (`r360gpu.metrics.inpainting`)
and summarises each (scene, method).  `results_document` is the ``results.json`` of the
``inpaint`` command (schema `r360gpu.protocol.INPAINT_SCHEMA`); its top-level keys::

    schema, r360gpu_version, created, protocol, mode, differs_from_script, inputs, methods,
    sources  {SCENE: {METHOD: {kind: "renders", path} or a rendered scene's description (kind "scene",
             path, frame, ...) with the test cameras' file}},
    lifted_targets {SCENE: {source, target, pre, gaussians, of, lifted_from, note}}: where masks were
             lifted (`r360gpu.pipeline.inpaint_target`); such a method's ``masks`` starts "lifted target",
    orbit    {SCENE: {against, requested, kept, dropped, no_orbit, methods {METHOD: as in scenes}}}: the
             metrics at orbit poses against the reference reconstruction (`r360gpu.pipeline.inpaint_orbit`),
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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.inpaint_folders import MethodFiles, SceneFiles, read_image, read_mask_binary, read_mask_script
from ..lift.orbit import check_pose_count
from ..metrics import json_values
from ..metrics.fid import fid_from_features, fid_image_files, kid_from_features
from ..metrics.inpainting import (METRICS, MODES, SET_METRICS, InpaintScene, overall_means, score_views,
                                  script_weights, summarise)
from ..protocol import INPAINT_SCHEMA
from ..render.sources import SceneSource
from .inpaint_orbit import OrbitScene, orbit_scores
from .inpaint_target import LIFTED_NOTE, LiftedMasks, lifted_masks
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
    sources: dict[str, dict[str, dict]] = field(default_factory=dict)
    targets: dict[str, dict] = field(default_factory=dict)
    orbits: dict[str, OrbitScene] = field(default_factory=dict)

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


def quantised(rgb: np.ndarray) -> np.ndarray:
    """A render as the benchmark's pipeline saves it before its script reads it back: torchvision's
    ``save_image`` (``x * 255 + 0.5`` clamped, truncated to uint8), then / 255 as `read_image` reads it."""
    q = np.clip(np.asarray(rgb, np.float32) * np.float32(255.0) + np.float32(0.5), 0, 255).astype(np.uint8)
    return q.astype(np.float32) / np.float32(255.0)


def open_scenes(scene: SceneFiles, frame: str | None) -> dict[str, SceneSource]:
    """A `SceneSource` for each method of ``scene`` given as a splat scene, in the world frame ``frame``
    names (`r360gpu.io.frames.resolve_frame`, with the scene's test cameras)."""
    from ..io.frames import resolve_frame

    out = {}
    try:
        for m in scene.methods:
            if m.scene is not None:
                with where(method=m.name):
                    out[m.name] = SceneSource(m.scene, frame=resolve_frame(frame, scene=m.scene,
                                                                           cameras=scene.camera_set))
    except BaseException:
        for s in out.values():
            s.release()
        raise
    return out


def score_scenes(scenes: list[SceneFiles], *, protocol: str, mode: str = "default", show_progress: bool = True,
                 frame: str | None = None, pre: str | None = None, target: str | None = None, orbit: int = 0,
                 reference: str | None = None, models: dict | None = None) -> InpaintRun:
    """Score every view of every scene and method; an unreadable or mismatched file is an InputError
    naming it, raised before anything is written.  A method given as a splat scene is rendered at the
    scene's test cameras (in compat mode saved to 8 bits first, as the benchmark's renders are);
    ``frame``: the world frame of those scenes (``score``'s ``--frame``).  ``pre`` and ``target``
    (``--pre``, ``--target``): the object's masks for the methods without any, lifted onto pre's
    Gaussians and rendered at the test cameras (`r360gpu.pipeline.inpaint_target`).  ``orbit`` > 0 with
    ``reference``: the splat methods also scored at that many orbit poses against the reference
    reconstruction's renders (`r360gpu.pipeline.inpaint_orbit`).

    models: ``lpips`` and ``lpips_spatial``, `r360gpu.metrics.fidelity.LpipsModel` plain and spatial
    exports (LPIPS, masked LPIPS; `r360gpu.metrics.inpainting.score_views`), and ``inception``, an
    `r360gpu.probes.inception.InceptionModel` (per-scene FID and KID, `fid_image_sets`).  A model not
    given leaves its metrics not computed, with the reason."""
    models = dict(models or {})
    inception = models.pop("inception", None)
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    if (pre is None) != (target is None):
        raise InputError("--pre and --target go together: the target is lifted onto pre's Gaussians")
    check_pose_count(orbit)
    if orbit and (reference is None or pre is None):
        raise InputError("--orbit needs --reference (the scene without the object, as splats) and --pre with "
                         "--target (the orbit circles the target)")
    t0 = time.perf_counter()
    results: list[InpaintScene] = []
    sources: dict[str, dict[str, dict]] = {}
    targets: dict[str, dict] = {}
    orbits: dict[str, OrbitScene] = {}
    for scene in scenes:
        lifted = None
        if pre is not None and any(m.masks is None for m in scene.methods):
            with where(scene=scene.name):
                lifted = lifted_masks(scene, pre, target, frame)
            targets[scene.name] = lifted.record
        splats = open_scenes(scene, frame)
        try:
            per_method, rendered = _score_scene(scene, splats, mode, show_progress, lifted, models,
                                                keep=inception is not None)
        finally:
            for s in splats.values():
                s.release()
        sources[scene.name] = {m.name: _describe(m, splats.get(m.name), scene) for m in scene.methods}
        for m in scene.methods:
            masks = (str(m.mask_folder) if m.mask_folder is not None else
                     f"{LIFTED_NOTE} ({lifted.record['source']})" if lifted is not None else None)
            results.append(summarise(scene.name, m.name, per_method[m.name], mode=mode, masks=masks))
        if inception is not None:
            ref_features = None
            for rec, m in zip(results[-len(scene.methods):], scene.methods):
                with where(scene=scene.name, method=m.name):
                    ref_files, out_files = fid_image_sets(protocol, scene, m)
                    if ref_features is None:
                        ref_features = _features(inception, ref_files, mode)
                    out = _features(inception, rendered.get(m.name, out_files), mode)
                    _set_metrics(rec, ref_features, out)
        if orbit:
            orbits[scene.name] = orbit_scores(scene, orbit, pre=pre, target=target, reference=reference, frame=frame,
                                              mode=mode, quantise=quantised, models=models)
    _warn_mixed_masks(scenes)
    return InpaintRun(protocol, mode, scenes, results, time.perf_counter() - t0, sources, targets, orbits)


def _describe(m: MethodFiles, source: SceneSource | None, scene: SceneFiles) -> dict:
    if source is None:
        return {"kind": "renders", "path": str(m.folder)}
    return {**source.describe(), "cameras": str(scene.camera_set)}


def _score_scene(scene: SceneFiles, splats: dict[str, SceneSource], mode: str, show_progress: bool,
                 lifted: LiftedMasks | None, models: dict, keep: bool) -> tuple[dict[str, list], dict[str, list]]:
    """The per-view records of each method; and, with ``keep``, the splat methods' renders as scored
    (FID and KID compare them with the photographs: no folder of theirs exists)."""
    per_method: dict[str, list] = {m.name: [] for m in scene.methods}
    rendered: dict[str, list] = {name: [] for name in splats} if keep else {}
    items = progress(list(enumerate(scene.photos)), desc=f"{scene.name}", enabled=show_progress)
    for i, photo_path in items:
        with where(scene=scene.name, view=photo_path.name):
            photo = read_image(photo_path, compat=mode == "compat")
            shape = photo.shape[:2]
            masks_read: dict[Path, np.ndarray] = {}
            renders, weights = [], []
            for m in scene.methods:
                with where(method=m.name):
                    if m.name in splats:
                        rgb = splats[m.name].images(photo_path.name, scene.cameras[i]).rgb
                        renders.append(quantised(rgb) if mode == "compat" else rgb)
                    else:
                        renders.append(read_image(m.renders[i], compat=mode == "compat"))
                        _size_check(renders[-1], shape, m.renders[i], photo_path)
                    if m.masks is not None and m.masks[i] not in masks_read:
                        masks_read[m.masks[i]] = _weights(m.masks[i], shape, mode)
                    weights.append(masks_read[m.masks[i]] if m.masks is not None else
                               lifted.masks[i] if lifted is not None else None)
            recs = score_views(photo_path.name, photo, renders, weights, mode=mode, **models)
            for m, rec in zip(scene.methods, recs):
                with where(method=m.name):
                    _warn_view(rec, mode, m.masks[i] if m.masks is not None else None)
                per_method[m.name].append(rec)
            for m, img in zip(scene.methods, renders):
                if m.name in rendered:
                    rendered[m.name].append(img)
    return per_method, rendered


def fid_image_sets(protocol: str, scene: SceneFiles, method: MethodFiles) -> tuple[list[Path], list[Path]]:
    """The two image sets FID and KID compare for a scene and method: for 360-USID every image
    pytorch-fid reads in the photographs' folder and in the renders' folder, as the script's
    ``calculate_fid_given_paths`` on the two folders (all of their files, not only the matched views);
    for SPIn-NeRF, whose ``images/`` also holds the training photographs with the object, the
    scored test photographs and the method's renders of them.  A method given as a splat scene has no
    folder: its side is empty here, and its renders at the test views stand for it."""
    renders = method.renders or []
    if protocol == "360usid":
        return fid_image_files(scene.photos[0].parent), fid_image_files(renders[0].parent) if renders else []
    return list(scene.photos), list(renders)


def _features(inception, images: list, mode: str) -> np.ndarray | None:
    """Inception features of image files (read as the script reads them) or of images in memory."""
    if len(images) < 2:
        return None
    return inception.features(read_image(p, compat=mode == "compat") if isinstance(p, Path) else p for p in images)


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
        "sources": run.sources,
        "lifted_targets": run.targets,
        "orbit": {name: json_values.enc_tree(o.to_dict()) for name, o in run.orbits.items()},
        "scenes": scenes,
        "overall": {m: json_values.enc_tree(overall_means(run.results, m)) for m in run.methods},
        "warnings": warnings,
    }
