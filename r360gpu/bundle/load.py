"""Load and check scene bundles: :func:`load_bundle`, :func:`check_bundle`, :func:`inspect_bundle`.

A bundle is a folder holding ``scene.toml`` (format in the package
docstring), or a folder in the public Remove360 evaluation layout
(:mod:`.remove360_layout`).  Checking collects EVERY problem before giving
up, so one run of ``r360gpu check`` lists all there is to fix.

What is checked:

* scene.toml: TOML syntax, required keys, unknown keys (with a suggestion),
  types and values, method names (not "pre"/"reference", no duplicates even
  ignoring case, usable as file names);
* cameras: loaded in full (every camera loader's own checks); view names
  (camera image stems) must be unique;
* masks: one ``<view>.png`` per evaluation view, with the camera's size;
  masks of views without a camera; ``check_bundle`` also decodes every mask,
  ``load_bundle`` reads only the PNG headers (the pipeline decodes them
  anyway, with the same errors);
* views: the selection is not empty, explicit names and patterns match;
* splat scenes: the file exists and its header is a 3DGS PLY / compressed
  PLY with Gaussians and a size that matches the header, or a ``.splat`` of
  whole 32-byte records; ``check_bundle`` (``deep``) also loads the Gaussians
  with the loader ``score`` uses (big scenes take seconds);
* renderings: an RGB (and, for pre and the methods, a depth) file for every
  evaluation view, whose header gives the view's size; ``check_bundle`` also
  decodes each with the reader ``score`` uses, so ``check`` OK means
  ``score`` reads every input it validates.
"""
from __future__ import annotations

import difflib
import fnmatch
import math
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from ..errors import InputError
from ..util import warning_log
from ..io.camera import Camera
from ..io.compressed_ply import check_compressed_header, is_compressed_ply
from ..io.inria_ply import check_inria_header, is_inria_ply
from ..io.load import latest_inria_iteration, load_cameras, load_gaussians
from ..io.masks import load_mask, mask_size
from ..io.paths import link_problem
from ..io.ply import read_ply_header
from ..io.renders import RendersReader, depth_size, image_size, read_depth, read_rgb
from .names import bad_name, name_problems
from .model import (DEPTH_MODES, PRINCIPAL_POINTS, RENDER_KEYS, RESERVED_METHOD_NAMES, Bundle, BundleError,
                    BundleOptions, Draft, Problem, RenderSettings, SourceSpec)
from .remove360_layout import is_remove360_folder, remove360_draft

CONFIG_NAME = "scene.toml"
TOP_KEYS = ("name", "prompt", "cameras", "masks", "views", "frame", "pre", "reference", "methods", "options",
            "expected", "target")
SOURCE_KEYS = ("scene", "renders", "rgb", "depth", "depth_scale", "frame") + RENDER_KEYS
OPTION_KEYS = ("background", "depth", "reference_free")
# Extensions stripped from camera image names to get view names.
_IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".bmp", ".webp")
_SPLAT_RECORD_BYTES = 32
_PLY_MAGIC = (b"ply\n", b"ply\r\n")
# Beyond this many problems of one kind in one folder, the rest is summarised in one line.
_MAX_LISTED = 10
_DUPLICATE_TABLE = re.compile(r"Cannot declare \('methods', '((?:[^'\\]|\\.)*)'\) twice(.*)")


def load_bundle(path: str | os.PathLike | Bundle, *, views: list[str] | None = None, prompt: str | None = None,
                method_name: str | None = None, frame: str | None = None) -> Bundle:
    """Load a bundle folder (or its scene.toml); raise :class:`BundleError` listing every problem.

    views: glob patterns over view names replacing scene.toml's ``views``.
    prompt: replaces scene.toml's ``prompt`` (for the Remove360 layout: instead
    of prompt.txt).  method_name: name of the Remove360 layout's method
    (default "after"); not used for scene.toml bundles.  frame: replaces
    scene.toml's top-level ``frame`` (the default of every splat scene; a
    source's own ``frame`` key still wins), e.g. ``"gsplat"`` (``--frame``).
    Masks are checked from their PNG headers (see the module docstring).
    A :class:`Bundle` already loaded is returned as it is.
    """
    if isinstance(path, Bundle):
        return path
    bundle, problems = inspect_bundle(path, views=views, prompt=prompt, method_name=method_name, frame=frame,
                                      deep=False)
    if problems:
        raise BundleError(path, problems)
    return bundle


def check_bundle(path: str | os.PathLike, *, views: list[str] | None = None, prompt: str | None = None,
                 method_name: str | None = None, frame: str | None = None) -> list[Problem]:
    """Every problem of a bundle ([] when it is valid); arguments as :func:`load_bundle`.
    Unlike :func:`load_bundle`, decodes every mask."""
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
        draft = _draft_from_config(root, config, problems, views=views, prompt=prompt)
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


# --- scene.toml ---------------------------------------------------------------------------------

def _draft_from_config(root: Path, config: Path, problems: list[Problem], *, views: list[str] | None,
                       prompt: str | None) -> Draft | None:
    cfg = str(config)

    def bad(message: str) -> None:
        problems.append(Problem(cfg, message))

    try:
        data = tomllib.loads(config.read_text(encoding="utf-8-sig"))  # a BOM is accepted
    except OSError as e:
        bad(f"cannot read: {e.strerror or e}")
        return None
    except UnicodeDecodeError:
        bad("not UTF-8 text")
        return None
    except tomllib.TOMLDecodeError as e:
        m = _DUPLICATE_TABLE.match(str(e))
        if m:
            bad(f"duplicate method: [methods.{m.group(1)}] is declared twice{m.group(2)}")
        else:
            bad(f"invalid TOML: {e}")
        return None

    d = Draft(root=root, layout="scene.toml", config=config)
    _unknown_keys(data, TOP_KEYS, None, bad)

    d.name = _default_name(root)
    if "name" in data:
        if isinstance(data["name"], str) and data["name"].strip():
            d.name = data["name"]
        else:
            bad("'name' must be a non-empty string")
    reason = bad_name(d.name)
    if reason:
        bad(f"scene name {d.name!r} {reason} (it names output folders); set name = \"...\"")

    if prompt is not None:
        if prompt.strip():
            d.prompt = prompt.strip()
        else:
            problems.append(Problem(None, "the prompt given is empty"))
    elif "prompt" not in data:
        bad("missing required key 'prompt': the category of the removed object, e.g. prompt = \"sofa\"")
    elif isinstance(data["prompt"], str) and data["prompt"].strip():
        d.prompt = data["prompt"].strip()
    else:
        bad("'prompt' must be a non-empty string")

    if "cameras" in data:
        if isinstance(data["cameras"], str) and data["cameras"].strip():
            d.cameras_path = root / data["cameras"]
        else:
            bad("'cameras' must be a path (a non-empty string)")
    if "frame" in data:
        d.frame = _frame_value(data["frame"], "", bad)
    if "target" in data:  # [target]: the object in 3D or by a few views' masks (bundle.target)
        from .target import parse_target_table

        d.target = parse_target_table(data["target"], root, bad)
    if "masks" not in data:
        if "target" not in data:
            bad("missing required key 'masks': the folder of target-mask PNGs, e.g. masks = \"masks\" "
                "(or a [target] table)")
    elif isinstance(data["masks"], str) and data["masks"].strip():
        d.masks_dir = root / data["masks"]
    else:
        bad("'masks' must be a folder path (a non-empty string)")

    if views is not None:
        d.view_patterns, d.patterns_origin = list(views), "--views"
    elif "views" in data:
        v = data["views"]
        if isinstance(v, list) and all(isinstance(p, str) and p for p in v):
            d.view_patterns, d.patterns_origin = list(v), f"views in {CONFIG_NAME}"
        else:
            bad("'views' must be a list of view names or glob patterns, e.g. views = [\"frame_0*\"]")

    if "pre" not in data:
        bad("missing required table [pre]: the original reconstruction, e.g. [pre] scene = \"pre.ply\"")
    else:
        d.pre = _parse_source(data["pre"], "[pre]", root, bad, depth_required=True)
    if "reference" in data:
        d.reference = _parse_source(data["reference"], "[reference]", root, bad, depth_required=False)
    methods = data.get("methods")
    if methods is None:
        bad("missing required table [methods.NAME]: one per evaluated method, e.g. [methods.mine] "
            "scene = \"mine.ply\"")
    elif not isinstance(methods, dict) or not methods:
        bad("'methods' must hold one table per method, e.g. [methods.mine] scene = \"mine.ply\"")
    else:
        for name, table in methods.items():
            if isinstance(table, dict) and "pre" in table:  # the method's own pre-removal source
                table = dict(table)
                d.method_pres[name] = _parse_source(table.pop("pre"), f"[methods.{name}.pre]", root, bad,
                                                    depth_required=True)
            d.methods[name] = _parse_source(table, f"[methods.{name}]", root, bad, depth_required=True,
                                            extra_keys=("pre",))

    if "options" in data:
        d.options = _parse_options(data["options"], bad)
    if "expected" in data:
        from .expected import parse_expected

        d.expected = parse_expected(data["expected"], list(d.methods), bad)
    return d


def _default_name(root: Path) -> str:
    return root.resolve().name


def _unknown_keys(table: dict, allowed: tuple[str, ...], where: str | None, bad) -> None:
    for key in table:
        if key in allowed:
            continue
        close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
        hint = f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(allowed)}"
        bad(f"unknown key '{key}'{f' in {where}' if where else ''} ({hint})")


def _parse_source(table, label: str, root: Path, bad, *, depth_required: bool,
                  extra_keys: tuple[str, ...] = ()) -> SourceSpec | None:
    if not isinstance(table, dict):
        bad(f"{label} must be a table, e.g. {label} scene = \"FILE.ply\" or renders = \"FOLDER\"")
        return None
    _unknown_keys(table, SOURCE_KEYS + extra_keys, label, bad)
    given = [k for k in ("scene", "renders", "rgb") if k in table]
    if len(given) != 1:
        found = f" (found {', '.join(given)})" if given else ""
        bad(f"{label} needs exactly one of 'scene' (a splat file) or 'renders' (a folder with rgb/ and "
            f"depth/){found}")
        return None
    key = given[0]
    value = table[key]
    if not (isinstance(value, str) and value.strip()):
        bad(f"{label} '{key}' must be a path (a non-empty string)")
        return None
    ok = True
    scale = 1.0
    if "depth_scale" in table:
        s = table["depth_scale"]
        if key == "scene":
            bad(f"{label} 'depth_scale' applies to renders only (a splat scene's depth is in scene units)")
            ok = False
        elif isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or s <= 0:
            bad(f"{label} 'depth_scale' must be a positive number, got {s!r}")
            ok = False
        else:
            scale = float(s)
    if "depth" in table and key != "rgb":
        bad(f"{label} 'depth' goes with 'rgb' (explicit folders); a renders folder's depth is its depth/ "
            f"sub-folder and a splat scene's depth is rendered")
        ok = False
    render = _parse_render_settings(table, label, bad, scene=key == "scene")
    frame = None
    if "frame" in table:
        if key != "scene":
            bad(f"{label} 'frame' applies to splat scenes only (renders are images already)")
            ok = False
        else:
            frame = _frame_value(table["frame"], f"{label} ", bad)
            ok = ok and frame is not None
    if not ok or render is None:
        return None
    if key == "scene":
        return SourceSpec("scene", root / value, render=render, frame=frame)
    if key == "renders":
        folder = root / value
        depth = folder / "depth"
        if not depth_required and not depth.exists():
            depth = None
        return SourceSpec("renders", folder, scale, folder / "rgb", depth)
    rgb = root / value
    depth = table.get("depth")
    if depth is not None and not (isinstance(depth, str) and depth.strip()):
        bad(f"{label} 'depth' must be a folder path (a non-empty string)")
        return None
    return SourceSpec("renders", rgb, scale, rgb, None if depth is None else root / depth)


def _parse_render_settings(table: dict, label: str, bad, *, scene: bool) -> RenderSettings | None:
    """The render keys of a source table (None after reporting a problem)."""
    given = [k for k in RENDER_KEYS if k in table]
    if given and not scene:
        bad(f"{label} {', '.join(repr(k) for k in given)} apply to splat scenes only (renders are images already)")
        return None
    ok = True

    def number(v) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

    if "antialiased" in table and not isinstance(table["antialiased"], bool):
        bad(f"{label} 'antialiased' must be true or false, got {table['antialiased']!r}")
        ok = False
    if "near" in table and not (number(table["near"]) and table["near"] > 0):
        bad(f"{label} 'near' must be a positive number (INRIA 0.2, gsplat 0.01), got {table['near']!r}")
        ok = False
    if "no_coverage_alpha" in table and not (number(table["no_coverage_alpha"])
                                             and 0 <= table["no_coverage_alpha"] <= 1):
        bad(f"{label} 'no_coverage_alpha' must be a number in [0, 1], got {table['no_coverage_alpha']!r}")
        ok = False
    if "principal_point" in table and table["principal_point"] not in PRINCIPAL_POINTS:
        bad(f"{label} 'principal_point' must be {' or '.join(map(repr, PRINCIPAL_POINTS))}, "
            f"got {table['principal_point']!r}")
        ok = False
    if not ok:
        return None
    return RenderSettings(**{k: (float(table[k]) if k in ("near", "no_coverage_alpha") else table[k]) for k in given})


def _frame_value(value, label: str, bad) -> str | None:
    """A ``frame`` key's value (None after reporting a problem); resolved once the cameras are known."""
    from ..io.frames import FRAME_KEYWORDS

    if isinstance(value, str) and value.strip():
        return value.strip()
    bad(f"{label}'frame' must be {', '.join(map(repr, FRAME_KEYWORDS))} or the path of a nerfstudio "
        f"dataparser_transforms.json, got {value!r}")
    return None


def _parse_options(table, bad) -> BundleOptions:
    opts = BundleOptions()
    if not isinstance(table, dict):
        bad("[options] must be a table")
        return opts
    _unknown_keys(table, OPTION_KEYS, "[options]", bad)
    if "background" in table:
        bg = table["background"]
        if (isinstance(bg, list) and len(bg) == 3
                and all(isinstance(c, (int, float)) and not isinstance(c, bool) and 0 <= c <= 1 for c in bg)):
            opts.background = tuple(float(c) for c in bg)
        else:
            bad(f"[options] 'background' must be three numbers in [0, 1] (RGB), got {bg!r}")
    if "depth" in table:
        mode = table["depth"]
        if mode in DEPTH_MODES:
            opts.depth = mode
        else:
            close = difflib.get_close_matches(str(mode), DEPTH_MODES, n=1, cutoff=0.6)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            bad(f"[options] 'depth' must be {' or '.join(map(repr, DEPTH_MODES))}, got {mode!r}{hint}")
    if "reference_free" in table:
        if isinstance(table["reference_free"], bool):
            opts.reference_free = table["reference_free"]
        else:
            bad(f"[options] 'reference_free' must be true or false, got {table['reference_free']!r}")
    return opts


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
        cameras = _load_cameras(draft.cameras_path, problems) if draft.cameras_path is not None else None
    masks = _list_masks(draft.masks_dir, problems) if draft.masks_dir is not None else None

    if getattr(draft, "target", None) is not None:  # every camera is a view; unmasked ones get rendered masks
        from .target import target_views

        views, masks = target_views(draft, where, cameras, masks, _list_masks, problems)
    else:
        views = _select_views(draft, where, cameras, masks, problems)
    named = name_problems("view", views)
    names_where = str(draft.masks_dir) if draft.masks_dir is not None else where
    _add_capped(problems, [Problem(names_where, p) for p in named], names_where, "view names")
    if named:
        views = []
    if getattr(draft, "target", None) is not None:
        sizes = {v: (cameras[v].height, cameras[v].width) for v in views} if cameras else {}
    else:
        sizes = _check_masks(views, cameras, masks or {}, draft, problems, deep=deep)

    resolved: dict[tuple[str, str | None], SourceSpec | None] = {}
    frames: dict = {}  # a frame recomputed once per value (gsplat's reads the whole COLMAP model)
    for role, name, spec in entries:
        label = _label(draft, role, name)
        if spec.kind == "scene":
            resolved[role, name] = _with_frame(_check_scene(spec, label, problems, deep=deep), spec, draft, label,
                                               frames, problems)
        else:
            _check_renders(spec, label, views, sizes, depth_required=role != "reference", where=where,
                           problems=problems, deep=deep)
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


def view_name(camera_name: str) -> str:
    """The view name of a camera: its image file name without folders and image extension."""
    base = camera_name.replace("\\", "/").rsplit("/", 1)[-1]
    stem, dot, ext = base.rpartition(".")
    return stem if dot and stem and f".{ext.lower()}" in _IMAGE_EXTENSIONS else base


def _load_cameras(path: Path, problems: list[Problem]) -> dict[str, Camera] | None:
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


def _list_masks(folder: Path, problems: list[Problem]) -> dict[str, Path] | None:
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
        problems.append(Problem(str(folder), f"{len(other)} mask(s) not in PNG: {_names(other)}; save them as "
                                             f"lossless .png (a view's mask is <view>.png)"))
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


def _names(views: list[str]) -> str:
    listed = ", ".join(repr(v) for v in views[:_MAX_LISTED])
    return listed + (f" and {len(views) - _MAX_LISTED} more" if len(views) > _MAX_LISTED else "")


def _select_views(draft: Draft, where: str, cameras: dict[str, Camera] | None, masks: dict[str, Path] | None,
                  problems: list[Problem]) -> list[str]:
    if masks is None:  # no usable masks folder: already reported
        return []
    if draft.view_patterns is None:
        selected = set(masks)
    else:
        universe = set(masks) | set(cameras or ())
        selected = set()
        for pat in draft.view_patterns:
            if _has_glob(pat):
                matched = fnmatch.filter(universe, pat)
                if not matched:
                    problems.append(Problem(where, f"pattern {pat!r} ({draft.patterns_origin}) matches no view"))
            else:
                matched = [pat] if pat in universe else []
                if not matched:
                    what = "no camera and no mask" if cameras is not None else "no mask"
                    problems.append(Problem(where, f"view {pat!r} ({draft.patterns_origin}) has {what}"))
            selected.update(matched)
        missing = sorted(v for v in selected if v not in masks)
        if missing:
            problems.append(Problem(str(draft.masks_dir), f"missing masks for {len(missing)} selected view(s): "
                                                          f"{_names(missing)} (expected <view>.png)"))
    if cameras is not None:
        orphans = sorted(v for v in selected if v in masks and v not in cameras)
        if orphans:
            problems.append(Problem(str(draft.masks_dir), f"masks for {len(orphans)} view(s) with no camera in "
                                                          f"{draft.cameras_path}: {_names(orphans)}"
                                                          f"{_near_miss(orphans, set(cameras) - set(masks))}"))
    views = sorted(v for v in selected if v in masks and (cameras is None or v in cameras))
    if not views and masks:  # (an empty masks folder is reported by _list_masks)
        why = (f"no view matches {draft.patterns_origin}" if draft.view_patterns is not None
               else "no mask has a matching camera" if cameras else "no masks")
        problems.append(Problem(where, f"no evaluation views ({why})"))
    return views


def _check_masks(views: list[str], cameras: dict[str, Camera] | None, masks: dict[str, Path], draft: Draft,
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
    _add_capped(problems, listed, str(draft.masks_dir), "masks")
    if deep and views and n_empty == len(views):
        problems.append(Problem(str(draft.masks_dir), no_target_message([masks[v] for v in views])))
    return sizes


def no_target_message(paths: list) -> str:
    """Why a selection whose every target mask is empty cannot be scored (names the masks)."""
    names = [Path(p).name for p in paths]
    return (f"every selected target mask is empty ({_names(names)}): no view shows the object, so there is "
            f"nothing to evaluate (a view with an empty mask is left out of every axis); check the masks "
            f"(non-zero pixel = target) or the view selection")


def require_target(views: list[str], mask_of, mask_paths: dict) -> None:
    """InputError unless some selected view's decoded target mask has a target pixel
    (stops at the first one found, so it costs one mask decode in the usual case)."""
    if views and not any(np.asarray(mask_of(v)).any() for v in views):
        paths = [mask_paths.get(v, v) for v in views]
        folder = Path(paths[0]).parent if not isinstance(paths[0], np.ndarray) else None
        if folder is None:
            raise InputError(f"every selected target mask is empty (views {_names(list(views))}): nothing to "
                             f"evaluate")
        raise InputError(no_target_message(paths), folder)


def _add_capped(problems: list[Problem], listed: list[Problem], folder: str, what: str) -> None:
    problems.extend(listed[:_MAX_LISTED])
    if len(listed) > _MAX_LISTED:
        problems.append(Problem(folder, f"... and {len(listed) - _MAX_LISTED} more {what} with problems"))


def _check_scene(spec: SourceSpec, label: str, problems: list[Problem], *, deep: bool = False) -> SourceSpec | None:
    p = Path(spec.path)
    try:
        if not p.exists():
            raise InputError(f"scene file is a {link_problem(p)}" if link_problem(p) else "no such file", p)
        if p.is_dir():
            p = latest_inria_iteration(p)
        suffix = p.suffix.lower()
        if suffix == ".splat":
            _check_splat(p)
        elif suffix == ".ply" or _starts_with(p, _PLY_MAGIC):
            _check_ply(p)
        else:
            raise InputError("unknown Gaussian-splat format; expected an INRIA 3DGS .ply, a .compressed.ply "
                             "or a .splat file", p)
        if deep:  # the loader score uses, with its checks (e.g. every Gaussian NaN): check OK = score loads it
            load_gaussians(p)
    except InputError as e:
        problems.append(Problem(e.path or str(p), f"{e.problem} (scene of {label})"))
        return None
    return replace(spec, path=p)


def _with_frame(checked: SourceSpec | None, declared: SourceSpec, draft: Draft, label: str, frames: dict,
                problems: list[Problem]) -> SourceSpec | None:
    """The checked scene source with its frame resolved (:func:`r360gpu.io.frames.resolve_frame`):
    its own ``frame``, else scene.toml's top-level one, else "auto"."""
    if checked is None:
        return None
    from ..io.frames import find_dataparser_transforms, resolve_frame

    value = declared.frame if declared.frame is not None else draft.frame
    # "auto" depends on the scene's folder (the declared path: an INRIA folder, not its PLY)
    key = (value, str(find_dataparser_transforms(declared.path)) if value in (None, "auto") else None)
    if key not in frames:
        try:
            frames[key] = resolve_frame(value, scene=declared.path, cameras=draft.cameras_path, root=draft.root)
        except InputError as e:
            frames[key] = e
    frame = frames[key]
    if isinstance(frame, InputError):
        problems.append(Problem(frame.path, f"{frame.problem} (frame of {label})"))
        return None
    return replace(checked, frame=frame)


def _starts_with(p: Path, prefixes: tuple[bytes, ...]) -> bool:
    try:
        with open(p, "rb") as f:
            return f.read(8).startswith(prefixes)
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", p) from None


def _check_splat(p: Path) -> None:
    size = p.stat().st_size
    if size == 0:
        raise InputError("empty .splat file (contains no Gaussians)", p)
    if size % _SPLAT_RECORD_BYTES:
        raise InputError(f"truncated .splat file: {size} bytes is not a multiple of the "
                         f"{_SPLAT_RECORD_BYTES}-byte record", p)


def _check_ply(p: Path) -> None:
    ply = read_ply_header(p)
    if not (is_inria_ply(ply) or is_compressed_ply(ply)):
        raise InputError("PLY file is not a Gaussian-splat scene (no 'vertex' element with x and rot_0, "
                         "and not a .compressed.ply)", p)
    if ply.element("vertex").count == 0:
        raise InputError("scene has no Gaussians (vertex count 0)", p)
    # The loaders' own header checks, so that `check OK` means the scene will load.
    if is_compressed_ply(ply):
        check_compressed_header(ply)
    else:
        check_inria_header(ply)
    if ply.format == "ascii" or any(el.has_lists for el in ply.elements):
        return
    with open(p, "rb") as f:
        head = f.read(1 << 20)
    end = head.find(b"end_header")
    offset = end + len(b"end_header")
    offset += 2 if head[offset:offset + 2] == b"\r\n" else 1
    expected = offset + sum(el.count * el.dtype().itemsize for el in ply.elements)
    size = p.stat().st_size
    if size < expected:
        raise InputError(f"truncated PLY file: {size} bytes, the header declares {expected}", p)
    if size > expected:
        raise InputError(f"PLY file has {size - expected} bytes more than the header declares", p)


def _check_renders(spec: SourceSpec, label: str, views: list[str], sizes: dict[str, tuple[int, int]], *,
                   depth_required: bool, where: str, problems: list[Problem], deep: bool = False) -> None:
    rgb_ok = spec.rgb_dir is not None and spec.rgb_dir.is_dir()
    if not rgb_ok:
        folder = spec.rgb_dir or spec.path
        broken = link_problem(folder)
        problems.append(Problem(str(folder), f"RGB folder of {label} is a {broken}" if broken
                                else f"RGB folder of {label} does not exist"))
    depth_dir = spec.depth_dir
    if depth_dir is None:
        if depth_required:
            problems.append(Problem(where, f"{label} has no depth: the geometric axis needs depth renderings "
                                           f"for pre and every method (a depth/ folder, or depth = \"FOLDER\")"))
    elif not depth_dir.is_dir():
        broken = link_problem(depth_dir)
        problems.append(Problem(str(depth_dir), f"depth folder of {label} is a {broken}" if broken
                                else f"depth folder of {label} does not exist"))
        depth_dir = None
    if not rgb_ok:
        return
    try:
        reader = RendersReader.from_dirs(spec.rgb_dir, depth_dir, spec.depth_scale)
    except InputError as e:
        problems.append(Problem(e.path, e.problem))
        return
    def decoded(header_size, read):  # deep: also decoded by the reader score uses (check OK = score reads it)
        return lambda path: (header_size(path), read(path))[0] if deep else header_size(path)

    kinds = [("RGB image", spec.rgb_dir, set(reader.views()), reader.rgb_path, decoded(image_size, read_rgb))]
    if reader.has_depth:
        kinds.append(("depth image", depth_dir, set(reader.depth_views()), reader.depth_path,
                      decoded(depth_size, lambda path: read_depth(path, reader.depth_scale))))
    for what, folder, available, lookup, size_of in kinds:
        missing = [v for v in views if v not in available]
        if missing:
            hint = reader.lossy_depth_hint(missing) if what == "depth image" else ""
            problems.append(Problem(str(folder), f"missing {what}s of {label} for {len(missing)} of {len(views)} "
                                                 f"views: {_names(missing)}{'; ' + hint if hint else ''}"))
        listed: list[Problem] = []
        for v in views:
            if v not in available:
                continue
            try:
                path = lookup(v)
                hw = size_of(path)
            except InputError as e:
                listed.append(Problem(e.path, e.problem))
                continue
            if v in sizes and tuple(hw) != sizes[v]:
                listed.append(Problem(str(path), f"{what} is {hw[1]}x{hw[0]}, the mask of view {v!r} is "
                                                 f"{sizes[v][1]}x{sizes[v][0]} ({label})"))
        _add_capped(problems, listed, str(folder), f"{what}s")
