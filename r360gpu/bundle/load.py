"""Load and check scene bundles: :func:`load_bundle`, :func:`check_bundle`, :func:`inspect_bundle`.

A bundle is a folder holding ``scene.toml`` (format in the package
docstring), or a folder in the public Remove360 evaluation layout
(:mod:`.remove360_layout`).  Checking collects EVERY problem before giving
up, so one run of ``r360gpu check`` lists all there is to fix.

What is checked, and by which module (this one assembles the :class:`~.model.Bundle`):

* scene.toml (:mod:`.scene_toml`): TOML syntax, required keys, unknown keys (with a suggestion),
  types and values, method names (not "pre"/"reference", no duplicates even
  ignoring case, usable as file names);
* cameras (:mod:`.views`): loaded in full (every camera loader's own checks); view names
  (camera image stems) must be unique;
* masks (:mod:`.views`): one ``<view>.png`` per evaluation view, with the camera's size;
  masks of views without a camera; ``check_bundle`` also decodes every mask,
  ``load_bundle`` reads only the PNG headers (the pipeline decodes them
  anyway, with the same errors);
* views (:mod:`.views`): the selection is not empty, explicit names and patterns match;
* splat scenes (:mod:`.sources`): the file exists and its header is a 3DGS PLY / compressed
  PLY with Gaussians and a size that matches the header, or a ``.splat`` of
  whole 32-byte records; ``check_bundle`` (``deep``) also loads the Gaussians
  with the loader ``score`` uses (big scenes take seconds);
* renderings (:mod:`.sources`): an RGB (and, for pre and the methods, a depth) file for every
  evaluation view, whose header gives the view's size; ``check_bundle`` also
  decodes each with the reader ``score`` uses, so ``check`` OK means
  ``score`` reads every input it validates.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..util import warning_log
from .model import RESERVED_METHOD_NAMES, Bundle, BundleError, Draft, Problem, SourceSpec, add_capped
from .names import name_problems
from .remove360_layout import is_remove360_folder, remove360_draft
from .scene_toml import CONFIG_NAME, draft_from_config
from .sources import check_orbit_renders, check_renders, check_scene, with_frame
from .views import cameras_by_view, check_masks, list_masks, narrow_views, select_views


def load_bundle(path: str | os.PathLike | Bundle, *, views: list[str] | None = None, prompt: str | None = None,
                method_name: str | None = None, frame: str | None = None) -> Bundle:
    """Load a bundle folder (or its scene.toml); raise `BundleError` listing every problem.

    views: glob patterns over view names replacing scene.toml's ``views`` (``--views``;
    case-sensitive, `matching`); the bundle records them (``view_patterns``).
    prompt: replaces scene.toml's ``prompt`` (for the Remove360 layout: instead
    of prompt.txt).  method_name: name of the Remove360 layout's method
    (default "after"); not used for scene.toml bundles.  frame: replaces
    scene.toml's top-level ``frame`` (the default of every splat scene; a
    source's own ``frame`` key still wins), e.g. ``"gsplat"`` (``--frame``).
    Masks are checked from their PNG headers (see the module docstring).
    A `Bundle` already loaded is returned as it is, with only the views ``views`` selects
    (`narrow_views`: a scene from objects or from METHOD=FOLDER folders).
    """
    if isinstance(path, Bundle):
        return path if views is None else narrow_views(path, views)
    bundle, problems = inspect_bundle(path, views=views, prompt=prompt, method_name=method_name, frame=frame,
                                      deep=False)
    if problems:
        raise BundleError(path, problems)
    return bundle


def check_bundle(path: str | os.PathLike, *, views: list[str] | None = None, prompt: str | None = None,
                 method_name: str | None = None, frame: str | None = None) -> list[Problem]:
    """Every problem of a bundle ([] when it is valid); arguments as `load_bundle`.
    Unlike `load_bundle`, decodes every mask."""
    return inspect_bundle(path, views=views, prompt=prompt, method_name=method_name, frame=frame, deep=True)[1]


def inspect_bundle(path: str | os.PathLike, *, views: list[str] | None = None, prompt: str | None = None,
                   method_name: str | None = None, frame: str | None = None,
                   deep: bool = True) -> tuple[Bundle | None, list[Problem]]:
    """``(bundle, problems)``: the bundle (None when there is any problem) and every problem found.

    deep: also decode every mask (else only PNG headers are read).
    """
    problems: list[Problem] = []
    located = _locate(Path(path), problems)
    if located is None:
        return None, problems
    root, config = located
    if config is not None:
        draft = draft_from_config(root, config, problems, views=views, prompt=prompt)
    else:
        draft = remove360_draft(root, prompt=prompt, method_name=method_name, problems=problems)
        if views is not None:
            draft.view_patterns, draft.patterns_origin = list(views), "--views"
    if draft is None:
        return None, problems
    if frame is not None:  # --frame: the default frame of every splat scene, as a top-level frame key
        if not any(s is not None and s.kind == "scene" for s in (draft.pre, draft.reference, *draft.methods.values())):
            problems.append(Problem(str(root), f"--frame {frame} applies to splat scenes; this bundle has "
                                               f"renders only (images already in the cameras' frame)"))
        draft.frame = frame
    bundle = _resolve(draft, problems, deep=deep)
    if bundle is not None and views is not None:
        bundle.view_patterns = tuple(views)  # selected here, once (views.narrow_views)
    return (None if problems else bundle), problems


# --- locating the bundle ------------------------------------------------------------------------

def _locate(path: Path, problems: list[Problem]) -> tuple[Path, Path | None] | None:
    if path.is_file() and path.suffix.lower() == ".toml":
        return path.parent, path
    if not path.exists():
        problems.append(Problem(str(path), "no such bundle folder"))
        return None
    if not path.is_dir():
        problems.append(Problem(str(path), f"not a bundle: expected a folder with {CONFIG_NAME} (or the "
                                           f"{CONFIG_NAME} itself)"))
        return None
    if (path / CONFIG_NAME).is_file():
        return path, path / CONFIG_NAME
    if is_remove360_folder(path):
        return path, None
    problems.append(Problem(str(path), f"not a bundle: no {CONFIG_NAME}, and not a Remove360 evaluation folder "
                                       f"(rgb/before, rgb/after, depth/before, depth/after, masks/)"))
    return None


# --- resolving and checking the files ------------------------------------------------------------

def _label(draft: Draft, role: str, name: str | None = None) -> str:
    if draft.layout == "scene.toml":
        return {"method": f"[methods.{name}]", "method_pre": f"[methods.{name}.pre]"}.get(role, f"[{role}]")
    return {"method": f"method {name!r}", "method_pre": f"pre of method {name!r}"}.get(role, role)


def _resolve(draft: Draft, problems: list[Problem], *, deep: bool) -> Bundle | None:
    where = str(draft.config) if draft.config is not None else str(draft.root)

    _check_method_names(draft, where, problems)
    if draft.layout != "scene.toml":  # (scene.toml's name is checked where it is parsed, with a hint)
        problems += [Problem(str(draft.root), p) for p in name_problems("scene", [draft.name])]
    # (role, method name, source): methods may not shadow pre/reference even when misnamed.
    entries = [("pre", None, draft.pre), ("reference", None, draft.reference)]
    entries += [("method", name, spec) for name, spec in draft.methods.items()]
    entries += [("method_pre", name, spec) for name, spec in draft.method_pres.items()]
    entries = [(role, name, spec) for role, name, spec in entries if spec is not None]

    scene_labels = [_label(draft, role, name) for role, name, spec in entries if spec.kind == "scene"]
    if draft.cameras_path is None and scene_labels:
        problems.append(Problem(where, f"missing key 'cameras': needed to render the splat scene of "
                                       f"{', '.join(scene_labels)}"))
    with warning_log.where(scene=draft.name):  # a camera loader's warning names the scene
        cameras = cameras_by_view(draft.cameras_path, problems) if draft.cameras_path is not None else None
    masks = list_masks(draft.masks_dir, problems) if draft.masks_dir is not None else None

    if getattr(draft, "target", None) is not None:  # every camera is a view; unmasked ones get rendered masks
        from .target import target_views

        views, masks = target_views(draft, where, cameras, masks, list_masks, problems)
    else:
        views = select_views(draft, where, cameras, masks, problems)
    named = name_problems("view", views)
    names_where = str(draft.masks_dir) if draft.masks_dir is not None else where
    add_capped(problems, [Problem(names_where, p) for p in named], names_where, "view names")
    if named:
        views = []
    if getattr(draft, "target", None) is not None:
        sizes = {v: (cameras[v].height, cameras[v].width) for v in views} if cameras else {}
    else:
        sizes = check_masks(views, cameras, masks or {}, draft, problems, deep=deep)

    resolved: dict[tuple[str, str | None], SourceSpec | None] = {}
    frames: dict = {}  # a frame recomputed once per value (gsplat's reads the whole COLMAP model)
    for role, name, spec in entries:
        label = _label(draft, role, name)
        if spec.kind == "scene":
            resolved[role, name] = with_frame(check_scene(spec, label, problems, deep=deep), spec, draft, label,
                                               frames, problems)
        else:
            check_renders(spec, label, views, sizes, depth_required=role != "reference", where=where,
                           problems=problems, deep=deep)
            if spec.orbit is not None and role in ("pre", "method_pre"):
                problems.append(Problem(where, f"{label} 'orbit' applies to methods and the reference: the "
                                               f"orbit is placed around pre's Gaussians, so pre is a splat scene"))
            elif spec.orbit is not None:
                check_orbit_renders(spec, label, problems, deep=deep)
            resolved[role, name] = spec
    if problems or draft.prompt is None or draft.pre is None:
        return None
    return Bundle(
        root=draft.root, name=draft.name, prompt=draft.prompt, views=views,
        cameras=None if cameras is None else {v: cameras[v] for v in views},
        masks={v: masks[v] for v in views if v in masks}, pre=resolved["pre", None],
        target=getattr(draft, "target", None),
        reference=resolved.get(("reference", None)),
        methods={name: resolved["method", name] for name in draft.methods}, options=draft.options,
        layout=draft.layout, config=draft.config, cameras_path=draft.cameras_path, expected=draft.expected,
        method_pres={name: resolved["method_pre", name] for name in draft.method_pres})


def _check_method_names(draft: Draft, where: str, problems: list[Problem]) -> None:
    problems += [Problem(where, p) for p in name_problems("method", list(draft.methods),
                                                          reserved=RESERVED_METHOD_NAMES)]


