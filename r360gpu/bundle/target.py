"""The ``[target]`` table of scene.toml: the object to remove given in 3D or by a few views' masks.

::

    [target]
    masks = "target_masks"        # masks of some views (as few as 2), lifted to pre's Gaussians
    indices = "target.npy"        # or: pre's Gaussian indices (.npy of ints or bools, or a .ply
    property = "label"            #     whose vertex property is non-zero on the target)
    box = { min = [..], max = [..] }   # or: the Gaussians whose centre is in a box
    # box = { centre = [..], size = [..], rotation = [w, x, y, z] or 3x3 }

With ``[target]`` the top-level ``masks`` is optional and every camera is an
evaluation view (``views`` still selects): views with a given mask (top-level
``masks`` or ``[target].masks``) keep it, the others get the lifted target's
mask rendered over pre (:mod:`r360gpu.lift`).  pre must be a splat scene.
Exactly one of ``indices``, ``box`` and ``masks`` defines the target, in that
order of precedence: indices, then box, then masks.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .model import Problem
from .views import matching

TARGET_KEYS = ("masks", "indices", "property", "box")


@dataclass(frozen=True)
class TargetSpec:
    """A declared target: ``masks`` (folder Path, or {view: (H, W) bool} from objects), ``indices``
    (Path, or an int / bool array from objects), ``prop`` (PLY property), ``box``
    (:class:`r360gpu.io.box.Box`)."""

    masks: object = None
    indices: object = None
    prop: str | None = None
    box: object = None

    @property
    def source(self) -> str:
        """What defines the target: "indices", "box" or "masks"."""
        return "indices" if self.indices is not None else "box" if self.box is not None else "masks"


def parse_target_table(value, root: Path, bad) -> TargetSpec | None:
    """The [target] table (``bad(message)`` reports a problem); None when unusable."""
    from ..errors import InputError
    from ..io.box import Box

    if not isinstance(value, dict):
        bad("[target] must be a table with masks, indices or box")
        return None
    unknown = sorted(set(value) - set(TARGET_KEYS))
    if unknown:
        bad(f"[target]: unknown key(s) {', '.join(unknown)} (known: {', '.join(TARGET_KEYS)})")
    if not any(k in value for k in ("masks", "indices", "box")):
        bad("[target] needs masks, indices or box")
        return None
    out = {}
    for key in ("masks", "indices"):
        if key in value:
            if isinstance(value[key], str) and value[key].strip():
                out[key] = root / value[key]
            else:
                bad(f"[target].{key} must be a path (a non-empty string)")
                return None
    if "property" in value:
        if not isinstance(value["property"], str) or not value["property"]:
            bad("[target].property must be a PLY property name")
            return None
        out["prop"] = value["property"]
        if not (isinstance(out.get("indices"), Path) and out["indices"].suffix.lower() == ".ply"):
            bad("[target].property names the vertex property of a .ply indices file (indices = \"....ply\"); "
                "without one it would be ignored")
            return None
    if "box" in value:
        try:
            out["box"] = Box.from_table(value["box"], where="[target].box")
        except InputError as e:
            bad(e.problem)
            return None
    return TargetSpec(**out)


def target_views(draft, where: str, cameras: dict | None, top_masks: dict | None, list_masks,
                 problems: list[Problem]) -> tuple[list[str], dict[str, Path]]:
    """(views, given masks) of a bundle with [target]: every camera (``views`` patterns still select);
    given masks from the top-level and [target] mask folders, checked against the cameras."""
    from ..io.masks import mask_size

    spec = draft.target
    if cameras is None:
        problems.append(Problem(where, "[target] needs 'cameras': every camera is an evaluation view"))
        return [], {}
    if draft.pre is not None and draft.pre.kind != "scene":
        problems.append(Problem(where, "[target] needs [pre] as a splat scene (scene = ...): the target's "
                                       "masks are rendered from pre's Gaussians"))
    if isinstance(spec.indices, Path) and not spec.indices.is_file():
        problems.append(Problem(str(spec.indices), "[target].indices: no such file"))
    given: dict[str, Path] = dict(top_masks or {})
    if isinstance(spec.masks, Path):
        extra = list_masks(spec.masks, problems) or {}
        twice = sorted(v for v, path in extra.items() if v in given and not _same_file(given[v], path))
        if twice:  # which one is the target? neither is read silently
            problems.append(Problem(where, f"{len(twice)} view(s) have a different mask in masks and in "
                                           f"[target].masks ({', '.join(str(extra[v]) for v in twice[:3])}"
                                           f"{', ...' if len(twice) > 3 else ''}); give each view's mask once"))
        given.update(extra)
    if spec.source == "masks" and not given:
        problems.append(Problem(where, "[target].masks gives no masks to lift the target from"))
    orphans = sorted(v for v in given if v not in cameras)
    if orphans:
        problems.append(Problem(where, f"target masks for {len(orphans)} view(s) with no camera: {orphans[:5]}"))
    views = sorted(cameras)
    if draft.view_patterns is not None:
        picked = set()
        for pat in draft.view_patterns:
            hit = matching(views, pat)
            if not hit:
                problems.append(Problem(where, f"pattern {pat!r} ({draft.patterns_origin}) matches no camera"))
            picked.update(hit)
        views = sorted(picked)
    for v, path in given.items():
        if v in cameras:
            try:
                hw = mask_size(path)
            except Exception as e:  # noqa: BLE001 (any unreadable header is one problem to report)
                problems.append(Problem(str(path), f"unreadable mask ({e})"))
                continue
            c = cameras[v]
            if hw != (c.height, c.width):
                problems.append(Problem(str(path), f"mask is {hw[1]}x{hw[0]}, the camera of view {v!r} is "
                                                   f"{c.width}x{c.height}"))
    return views, {v: p for v, p in given.items() if v in cameras}


def _same_file(a: Path, b: Path) -> bool:
    """Whether two mask files are one file or hold the same bytes (an unreadable one: not the same)."""
    try:
        return a.resolve() == b.resolve() or a.read_bytes() == b.read_bytes()
    except OSError:
        return False


def target_from_objects(target: dict, views: list[str]) -> TargetSpec:
    """A TargetSpec from ``scene_from_objects``'s ``target`` {"masks": {view: mask}, "indices": array,
    "box": table}."""
    from ..errors import InputError
    from ..io.box import Box

    if not isinstance(target, dict) or not set(target) & {"masks", "indices", "box"}:
        raise InputError("target must be a dict with 'masks', 'indices' or 'box'")
    unknown = sorted(set(target) - {"masks", "indices", "box"})
    if unknown:
        raise InputError(f"target: unknown key(s) {unknown}")
    from ..io.indices import index_array

    masks = target.get("masks")
    if masks is not None:
        if not isinstance(masks, dict):
            raise InputError(f"target['masks'] must be a dict {{view: (H, W) mask}}, got a {type(masks).__name__}")
        missing = sorted(set(masks) - set(views))
        if missing:
            raise InputError(f"target masks for views without a camera: {missing[:5]}")
        masks = {v: _mask_array(m, f"target['masks'][{v!r}]") for v, m in masks.items()}
    box = target.get("box")
    if box is not None and not isinstance(box, Box):
        box = Box.from_table(box, where="target['box']")
    indices = target.get("indices")
    return TargetSpec(masks=masks, indices=None if indices is None else index_array(indices, "target['indices']"),
                      box=box)


def _mask_array(value, where: str) -> np.ndarray:
    """A given target mask as an (H, W) array of numbers or booleans (InputError naming ``where``)."""
    from ..errors import InputError

    try:
        m = np.asarray(value)
    except (TypeError, ValueError):
        m = None
    if m is None or m.dtype.kind not in "biuf" or m.ndim != 2:
        raise InputError(f"{where} must be an (H, W) array of booleans or numbers, got "
                         f"{type(value).__name__}{'' if m is None else f' of {m.dtype}, shape {m.shape}'}")
    if m.dtype.kind == "f" and np.isnan(m).any():  # NaN != 0 would read as target
        raise InputError(f"{where}: the mask is NaN at {int(np.isnan(m).sum())} pixels; a mask is non-zero on the "
                         f"target and 0 elsewhere")
    return m
