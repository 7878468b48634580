"""Scene bundles: everything needed to score the methods of one scene, in one folder.

A bundle is a folder with a ``scene.toml`` (paths relative to the folder)::

    name = "room"            # scene name (default: the folder name)
    prompt = "sofa"          # category prompt of the semantic probe (required)
    cameras = "cameras"      # anything r360gpu.io.load_cameras accepts; required when a source is a splat scene
    masks = "masks"          # folder of target masks <view>.png, any non-zero pixel = target (required)
    views = ["frame_0*"]     # optional glob patterns selecting the evaluation views
    frame = "auto"           # optional: the world frame of every splat scene (docs/your-scene.md): "auto"
                             #   (dataparser_transforms.json beside the scene, else the cameras'), "cameras",
                             #   "gsplat", "gsplat-noflip" or a dataparser_transforms.json; also per source

    [pre]                    # the original reconstruction (required): exactly one of
    scene = "pre.ply"        #   a splat file (.ply, .compressed.ply, .splat) or INRIA output folder,
    # renders = "renders/pre"  #   a folder with rgb/<view>.png|jpg and depth/<view>.png|exr|npy|tiff,
    # rgb = "r/pre_rgb"      #   or explicit folders: rgb = ... with depth = ...
    # depth = "r/pre_depth"
    # depth_scale = 0.001    # renders only: multiply depth values (e.g. 16-bit PNG in mm -> m)

    [reference]              # optional: reconstruction of the physical post-removal capture
    scene = "ref.ply"        #   (same keys as [pre]; its depth is optional)

    [methods.clean]          # one table per evaluated method, key = method name (at least one)
    scene = "methods/clean.ply"

    [methods.objectclear]
    renders = "methods/objectclear"
    [methods.objectclear.pre]  # optional: the method's own pre-removal source (same keys as [pre]),
    renders = "methods/oc_pre" #   for its IoU_pre / IoU_drop, D_pre and reference-free s_str

    [options]                # all optional
    background = [0.0, 0.0, 0.0]   # render background, RGB in [0, 1]
    depth = "expected"             # splat depth: "expected" (sum w z / sum w) or "median"
    reference_free = false         # s_str = 1 - sim(pre, post) even with a reference

View names are the cameras' image stems (``images/frame_0001.jpg`` is view
``frame_0001``); masks and renderings are named ``<view>.<ext>``.  Without
``views``, the evaluation views are the views that have a mask (as in the
public Remove360 code); every one of them must then have a camera when
``cameras`` is given, and an RGB (and depth) rendering in every renders
source.  With ``views``, every selected name must have a mask (and camera).

A folder in the public Remove360 evaluation layout (``rgb/{before,after}``,
``depth/{before,after}``, ``masks/``) without scene.toml is also a bundle:
see :mod:`.remove360_layout`; several such folders of one scene (one per
method) are joined by :mod:`.group`, which also reads a benchmark root
``ROOT/<method>/<scene>/``.

Entry points: :func:`load_bundle` (raises :class:`BundleError` listing every
problem), :func:`check_bundle` (the problems as a list), :func:`inspect_bundle`.
"""
from __future__ import annotations

from .load import CONFIG_NAME, check_bundle, inspect_bundle, load_bundle, view_name
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
