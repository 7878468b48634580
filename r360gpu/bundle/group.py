"""Several methods' folders of one scene read as one bundle, and a benchmark root of them.

The public Remove360 layout holds ONE method run per folder (its own
``rgb/before`` + ``depth/before`` and ``rgb/after`` + ``depth/after``), and
every pipeline renders its own pre-removal scene.  :func:`group_scene` joins
the folders of one scene, ``{method: folder}``, into one :class:`Bundle`
whose methods each keep their own pre (``Bundle.method_pres``), so the
scene's methods are ranked against each other.  :func:`load_benchmark` reads
``ROOT/<method>/<scene>/`` (the paper's scenes x methods) into one bundle
per scene.

A member folder may also be a scene.toml bundle: its one method becomes the
member's method (several methods become ``<member>.<method>``), scored
against that bundle's pre (or the method's own).  The views must be the same
in every member.  Masks and cameras come from the first member (the
dataset's masks are the same for every method); cameras of later members
must agree with them where both have one.  The prompt is ``prompt`` when
given, else it must agree across members.  The reference is the first
member's that has one.
"""
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from .load import inspect_bundle
from .model import Bundle, BundleError, Problem
from .names import RESERVED_METHOD_NAMES, check_names

GROUP_LAYOUT = "group"


def group_scene(members: dict, *, scene_name: str | None = None, prompt: str | None = None,
                views: list[str] | None = None) -> Bundle:
    """One bundle from ``{method: folder}`` (folders of one scene, one method run each); see the module
    docstring.  Raises :class:`BundleError` listing every member's problems, :class:`InputError` when the
    members disagree (views, prompt, cameras)."""
    if not members:
        raise InputError("no method folders to group")
    loaded: dict[str, Bundle] = {}
    problems: list[Problem] = []
    for method, folder in members.items():
        bundle, found = inspect_bundle(folder, views=views, prompt=prompt, method_name=method, deep=False)
        problems += found
        if bundle is not None:
            loaded[method] = bundle
    first_folder = next(iter(members.values()))
    if problems:
        raise BundleError(first_folder, problems)
    base = next(iter(loaded.values()))
    name = scene_name or base.name
    methods, method_pres = {}, {}
    cameras, cameras_path, reference = base.cameras, base.cameras_path, base.reference
    prompts = {}
    for member, b in loaded.items():
        if b.views != base.views:
            only = sorted(set(b.views) ^ set(base.views))
            raise InputError(f"scene {name!r}: the methods' folders have different views ({b.root} and "
                             f"{base.root} differ in {len(only)}: {', '.join(only[:5])}"
                             f"{' ...' if len(only) > 5 else ''})")
        prompts.setdefault(b.prompt, b.root)
        if b.cameras is not None:
            if cameras is None:
                cameras, cameras_path = b.cameras, b.cameras_path
            else:
                _same_cameras(cameras, b.cameras, b.root, name)
        if reference is None and b.reference is not None:
            reference = b.reference
        inner = list(b.methods)
        for m in inner:
            key = member if len(inner) == 1 else f"{member}.{m}"
            if key in methods:
                raise InputError(f"scene {name!r}: method {key!r} is given twice")
            methods[key] = b.methods[m]
            method_pres[key] = b.pre_of(m)
    check_names("scene", [name])
    check_names("method", list(methods), reserved=RESERVED_METHOD_NAMES)
    if len(prompts) > 1:
        listed = "; ".join(f"{p!r} in {root}" for p, root in prompts.items())
        raise InputError(f"scene {name!r}: the methods' folders give different prompts ({listed}); "
                         f"pass --prompt")
    return replace(base, name=name, cameras=cameras, cameras_path=cameras_path, reference=reference,
                   methods=methods, method_pres=method_pres, pre=method_pres[next(iter(methods))],
                   layout=GROUP_LAYOUT, config=None)


def _same_cameras(a: dict, b: dict, root, scene: str) -> None:
    for v, ca in a.items():
        cb = b.get(v)
        if cb is None:
            continue
        same = (ca.width, ca.height) == (cb.width, cb.height) and np.allclose(
            [ca.fx, ca.fy, ca.cx, ca.cy], [cb.fx, cb.fy, cb.cx, cb.cy], rtol=1e-6) and np.allclose(
            ca.R, cb.R, atol=1e-6) and np.allclose(ca.t, cb.t, atol=1e-6 * max(1.0, float(np.abs(ca.t).max())))
        if not same:
            raise InputError(f"scene {scene!r}: the camera of view {v!r} in {root} differs from the first "
                             f"method's; the methods of one scene must be evaluated at the same poses")


def parse_method_folders(args: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
    """Split command-line bundle arguments into plain folders and ``METHOD=FOLDER`` pairs.

    An argument is a pair when it is not an existing path, has ``=`` and the
    text before it names no path (no separator)."""
    plain, pairs = [], []
    for a in args:
        method, eq, folder = a.partition("=")
        if eq and not os.path.exists(a) and "/" not in method and "\\" not in method:
            if not method or not folder:
                raise InputError(f"{a!r}: a METHOD=FOLDER pair needs both a method name and a folder")
            pairs.append((method, folder))
        else:
            plain.append(a)
    return plain, pairs


def group_pairs(pairs: list[tuple[str, str]], *, scene_name: str | None = None, prompt: str | None = None,
                views: list[str] | None = None) -> list[Bundle]:
    """One bundle per scene from ``(method, folder)`` pairs: folders are grouped by their name (every
    pair is one scene with ``scene_name``)."""
    groups: dict[str, dict] = {}
    for method, folder in pairs:
        key = scene_name or Path(folder).resolve().name
        members = groups.setdefault(key, {})
        if method in members:
            raise InputError(f"method {method!r} is given twice for scene {key!r} ({members[method]} and "
                             f"{folder})")
        members[method] = folder
    return [group_scene(m, scene_name=scene_name, prompt=prompt, views=views) for m in groups.values()]


def load_benchmark(root: str | os.PathLike, *, prompt: str | None = None,
                   views: list[str] | None = None) -> tuple[list[Bundle], list[str]]:
    """``(bundles, notes)`` of a benchmark root ``ROOT/<method>/<scene>/``: one bundle per scene (sorted
    by name) with the methods that have a folder for it (sorted); ``notes`` name the missing ones."""
    root = Path(root)
    if not root.is_dir():
        raise InputError("benchmark root is not a folder (expected ROOT/<method>/<scene>/)", root)
    methods = sorted(p.name for p in _folders(root))
    if not methods:
        raise InputError("benchmark root has no method folders (expected ROOT/<method>/<scene>/)", root)
    scenes: dict[str, dict] = {}
    for m in methods:
        for s in sorted(p.name for p in _folders(root / m)):
            scenes.setdefault(s, {})[m] = root / m / s
    if not scenes:
        raise InputError("benchmark root has no scene folders under its method folders "
                         "(expected ROOT/<method>/<scene>/)", root)
    notes = []
    for s in sorted(scenes):
        missing = [m for m in methods if m not in scenes[s]]
        if missing:
            notes.append(f"scene {s}: no folder for method{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(missing)} (expected {root / missing[0] / s})")
    bundles = [group_scene(scenes[s], scene_name=s, prompt=prompt, views=views) for s in sorted(scenes)]
    return bundles, notes


def _folders(folder: Path) -> list[Path]:
    """The visible sub-folders of ``folder``; a symbolic link that leads nowhere (dangling, or a
    loop) is an InputError naming it, not a folder silently left out."""
    try:
        entries = sorted(folder.iterdir())
    except OSError as e:
        raise InputError(f"cannot list the folder: {e.strerror or e}", folder) from None
    out = []
    for p in entries:
        if p.name.startswith("."):
            continue
        if p.is_symlink() and not p.exists():
            raise InputError(f"symbolic link to {os.readlink(p)!r}, which does not exist (or is a link loop)", p)
        if p.is_dir():
            out.append(p)
    return out
