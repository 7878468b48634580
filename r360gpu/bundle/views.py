"""The evaluation views of a bundle: cameras by view name, the masks folder, the view selection,
and each selected view's mask checked against its camera.

The view selection (scene.toml's ``views``, ``--views``, ``EvaluateOptions.views``) follows one
rule, :func:`matching`, and is made once per scene: where its folder is loaded
(:func:`select_views`), or, for a scene built otherwise (METHOD=FOLDER groups, ``--benchmark``
scenes, scenes from objects), by :func:`narrow_views`.
"""
from __future__ import annotations

import difflib
import fnmatch
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.camera import Camera
from ..io.load import load_cameras
from ..io.masks import load_mask, mask_size
from ..io.paths import link_problem
from .model import Draft, Problem, add_capped, listed_names

# Extensions stripped from camera image names to get view names.
_IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".bmp", ".webp")


def view_name(camera_name: str) -> str:
    """The view name of a camera: its image file name without folders and image extension."""
    base = camera_name.replace("\\", "/").rsplit("/", 1)[-1]
    stem, dot, ext = base.rpartition(".")
    return stem if dot and stem and f".{ext.lower()}" in _IMAGE_EXTENSIONS else base


def cameras_by_view(path: Path, problems: list[Problem]) -> dict[str, Camera] | None:
    """The cameras of ``path`` by view name (None when they cannot be loaded); two cameras with
    one view name, or none at all, are problems."""
    try:
        cams = load_cameras(path)
    except InputError as e:
        problems.append(Problem(e.path or str(path), e.problem))
        return None
    out: dict[str, Camera] = {}
    owners: dict[str, str] = {}
    for cam in cams:
        v = view_name(cam.name)
        if v in out:
            problems.append(Problem(str(path), f"cameras {owners[v]!r} and {cam.name!r} have the same view name "
                                               f"{v!r} (views are named by image stem)"))
            continue
        out[v], owners[v] = cam, cam.name
    if not out:
        problems.append(Problem(str(path), "no cameras"))
    return out


def list_masks(folder: Path, problems: list[Problem]) -> dict[str, Path] | None:
    """The ``<view>.png`` masks of ``folder`` by view name (None when it is not a readable folder);
    masks in another image format, duplicates and broken links are problems."""
    if not folder.is_dir():
        broken = link_problem(folder)
        problems.append(Problem(str(folder), f"masks folder is a {broken}" if broken
                                else "masks folder does not exist" if not folder.exists()
                                else "masks must be a folder of <view>.png files"))
        return None
    masks: dict[str, Path] = {}
    other: list[str] = []
    try:
        entries = sorted(folder.iterdir())
    except OSError as e:
        problems.append(Problem(str(folder), f"cannot list masks folder: {e.strerror or e}"))
        return None
    for p in entries:
        if p.name.startswith("."):
            continue
        if not p.is_file():
            broken = link_problem(p)
            if broken and p.suffix.lower() in _IMAGE_EXTENSIONS:
                problems.append(Problem(str(p), f"mask is a {broken}"))
            elif p.suffix.lower() in _IMAGE_EXTENSIONS and p.is_dir():  # e.g. masks/view.png/ made by a script
                problems.append(Problem(str(p), "is a folder, not a mask image"))
            continue
        if p.suffix.lower() == ".png":
            if p.stem in masks:
                problems.append(Problem(str(folder), f"several masks for view {p.stem!r}: "
                                                     f"{masks[p.stem].name}, {p.name}"))
                continue
            masks[p.stem] = p
        elif p.suffix.lower() in _IMAGE_EXTENSIONS:
            other.append(p.name)
    if not masks:
        found = f" (found {len(other)} other images, e.g. {other[0]}: masks must be PNG)" if other else ""
        problems.append(Problem(str(folder), f"masks folder has no <view>.png masks{found}"))
    elif other:  # a view's mask in a lossy or other format would silently leave the evaluation
        problems.append(Problem(str(folder), f"{len(other)} mask(s) not in PNG: {listed_names(other)}; save them "
                                             f"as lossless .png (a view's mask is <view>.png)"))
    return masks


def _near_miss(names: list[str], others: set[str]) -> str:
    """Why a mask's view has no camera when a camera's view name is nearly the same: the two names
    shown with their differences visible (spaces, case, Unicode forms)."""
    for n in names:
        close = difflib.get_close_matches(n, sorted(others), n=1, cutoff=0.8)
        if close:
            return (f" (the mask {n!r} and the camera view {close[0]!r} differ only slightly: view names are "
                    f"compared exactly, spaces, case and accents included)")
    return ""


def _has_glob(pattern: str) -> bool:
    return any(c in pattern for c in "*?[")


def matching(names, pattern: str) -> list[str]:
    """The names ``pattern`` selects, in their order: the one rule of every view selection.

    Shell-style globs (``*``, ``?``, ``[seq]``, ``[!seq]``) matched case-sensitively on every OS
    (:func:`fnmatch.fnmatchcase`; ``fnmatch.filter`` would fold case where the OS's paths do), so a
    selection is the same on Linux, macOS and Windows: ``View_00*`` does not select ``view_001``.
    A pattern without those characters selects the view of exactly that name.
    """
    return [n for n in names if fnmatch.fnmatchcase(n, pattern)]


def narrow_views(bundle, patterns):
    """``bundle`` keeping only the views ``patterns`` select (:func:`matching`), with their cameras
    and masks: the selection of a scene that was not loaded from its folder with these patterns
    (METHOD=FOLDER groups, ``--benchmark`` scenes, scenes from objects).  A bundle these patterns
    selected already (``bundle.view_patterns``) is returned as it is.  A pattern that selects none
    of its views is an InputError naming the pattern and the scene's folder.
    """
    from dataclasses import replace

    patterns = tuple(patterns)
    if bundle.view_patterns == patterns:
        return bundle
    where = bundle.config or (None if bundle.layout == "objects" else bundle.root)
    selected: set = set()
    for p in patterns:
        hit = matching(bundle.views, p)
        if not hit:
            what = "matches no evaluation view" if _has_glob(p) else "is not an evaluation view (no mask?)"
            raise InputError(f"--views {p!r} {what} of scene {bundle.name!r}; its views are named like "
                             f"{list(bundle.views[:3])} (patterns are case-sensitive)", where)
        selected.update(hit)
    views = [v for v in bundle.views if v in selected]
    cameras = None if bundle.cameras is None else {v: bundle.cameras[v] for v in views if v in bundle.cameras}
    return replace(bundle, views=views, cameras=cameras, masks={v: m for v, m in bundle.masks.items() if v in views},
                   view_patterns=patterns)


def select_views(draft: Draft, where: str, cameras: dict[str, Camera] | None, masks: dict[str, Path] | None,
                  problems: list[Problem]) -> list[str]:
    """The evaluation views, sorted: every view with a mask, or those the draft's patterns select
    (:func:`matching`);
    a view needs a mask, and a camera when the bundle has cameras.  Patterns that select nothing,
    selected views without a mask and masks without a camera are problems."""
    if masks is None:  # no usable masks folder: already reported
        return []
    if draft.view_patterns is None:
        selected = set(masks)
    else:
        universe = set(masks) | set(cameras or ())
        selected = set()
        for pat in draft.view_patterns:
            matched = matching(universe, pat)
            if _has_glob(pat):
                if not matched:
                    problems.append(Problem(where, f"pattern {pat!r} ({draft.patterns_origin}) matches no view"))
            else:
                if not matched:
                    what = "no camera and no mask" if cameras is not None else "no mask"
                    problems.append(Problem(where, f"view {pat!r} ({draft.patterns_origin}) has {what}"))
            selected.update(matched)
        missing = sorted(v for v in selected if v not in masks)
        if missing:
            problems.append(Problem(str(draft.masks_dir), f"missing masks for {len(missing)} selected view(s): "
                                                          f"{listed_names(missing)} (expected <view>.png)"))
    if cameras is not None:
        orphans = sorted(v for v in selected if v in masks and v not in cameras)
        if orphans:
            problems.append(Problem(str(draft.masks_dir), f"masks for {len(orphans)} view(s) with no camera in "
                                                          f"{draft.cameras_path}: {listed_names(orphans)}"
                                                          f"{_near_miss(orphans, set(cameras) - set(masks))}"))
    views = sorted(v for v in selected if v in masks and (cameras is None or v in cameras))
    if not views and masks:  # (an empty masks folder is reported by list_masks)
        why = (f"no view matches {draft.patterns_origin}" if draft.view_patterns is not None
               else "no mask has a matching camera" if cameras else "no masks")
        problems.append(Problem(where, f"no evaluation views ({why})"))
    return views


def check_masks(views: list[str], cameras: dict[str, Camera] | None, masks: dict[str, Path], draft: Draft,
                 problems: list[Problem], *, deep: bool) -> dict[str, tuple[int, int]]:
    """(H, W) of every evaluation view whose mask could be read; reports unreadable masks and
    masks whose size differs from the camera's."""
    sizes: dict[str, tuple[int, int]] = {}
    listed: list[Problem] = []
    n_empty = 0
    for v in views:
        path = masks[v]
        try:
            if deep:
                m = load_mask(path)
                hw = m.shape
                n_empty += not m.any()
            else:
                hw = mask_size(path)
        except InputError as e:
            listed.append(Problem(str(path), e.problem))
            continue
        if cameras is not None:
            cam = cameras[v]
            if tuple(hw) != (cam.height, cam.width):
                listed.append(Problem(str(path), f"mask is {hw[1]}x{hw[0]}, the camera of view {v!r} is "
                                                 f"{cam.width}x{cam.height}"))
                continue
        sizes[v] = (int(hw[0]), int(hw[1]))
    add_capped(problems, listed, str(draft.masks_dir), "masks")
    if deep and views and n_empty == len(views):
        problems.append(Problem(str(draft.masks_dir), no_target_message([masks[v] for v in views])))
    return sizes


def no_target_message(paths: list) -> str:
    """Why a selection whose every target mask is empty cannot be scored (names the masks)."""
    names = [Path(p).name for p in paths]
    return (f"every selected target mask is empty ({listed_names(names)}): no view shows the object, so there "
            f"is nothing to evaluate (a view with an empty mask is left out of every axis); check the masks "
            f"(non-zero pixel = target) or the view selection")


def require_target(views: list[str], mask_of, mask_paths: dict) -> None:
    """InputError unless some selected view's decoded target mask has a target pixel
    (stops at the first one found, so it costs one mask decode in the usual case)."""
    if views and not any(np.asarray(mask_of(v)).any() for v in views):
        paths = [mask_paths.get(v, v) for v in views]
        folder = Path(paths[0]).parent if not isinstance(paths[0], np.ndarray) else None
        if folder is None:
            raise InputError(f"every selected target mask is empty (views {listed_names(list(views))}): nothing "
                             f"to evaluate")
        raise InputError(no_target_message(paths), folder)
