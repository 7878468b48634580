"""Scene bundles: everything needed to score the methods of one scene, in one folder.

A bundle is a folder with a ``scene.toml`` (paths relative to the folder).  Its
format (keys, views, renderings, the public layout) is described once, in
``docs/scene-toml.md`` of the repository; ``check_bundle`` and ``load_bundle``
are what enforce it.

A folder in the public Remove360 evaluation layout (``rgb/{before,after}``,
``depth/{before,after}``, ``masks/``) without scene.toml is also a bundle:
see `.remove360_layout`; several such folders of one scene (one per
method) are joined by `.group`, which also reads a benchmark root
``ROOT/<method>/<scene>/``.

Entry points: `load_bundle` (raises `BundleError` listing every
problem), `check_bundle` (the problems as a list), `inspect_bundle`.
"""
from __future__ import annotations

from .load import check_bundle, inspect_bundle, load_bundle
from .scene_toml import CONFIG_NAME
from .views import view_name
from .model import (DEPTH_MODES, RESERVED_METHOD_NAMES, Bundle, BundleError, BundleOptions, Problem,
                    SourceSpec)
from .group import group_pairs, group_scene, load_benchmark, parse_method_folders
from .objects import is_from_objects, scene_from_objects
from .remove360_layout import DEFAULT_METHOD_NAME, PROMPT_FILE, is_remove360_folder

__all__ = [
    "Bundle", "BundleOptions", "SourceSpec", "Problem", "BundleError",
    "load_bundle", "check_bundle", "inspect_bundle", "view_name", "is_remove360_folder",
    "scene_from_objects", "is_from_objects",
    "group_scene", "group_pairs", "load_benchmark", "parse_method_folders",
    "CONFIG_NAME", "RESERVED_METHOD_NAMES", "DEPTH_MODES", "DEFAULT_METHOD_NAME", "PROMPT_FILE",
]
