"""Scenes built from in-memory objects (no files): library use from another pipeline."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .model import Bundle, BundleOptions
from .names import RESERVED_METHOD_NAMES, check_bundle_names, check_names


def scene_from_objects(name: str, prompt: str, masks: dict, pre, methods: dict, *, reference=None,
                       cameras: dict | None = None, background=(0.0, 0.0, 0.0), depth: str = "expected",
                       reference_free: bool = False, method_pres: dict | None = None, target: dict | None = None
                       ) -> Bundle:
    """A scene to pass to `r360gpu.evaluate` without files.

    masks: {view: bool (H, W) target mask}; the keys are the evaluation views.
    pre, reference, methods[...]: each a `Gaussians`
        (rendered at ``cameras``), a
        `DeviceViewsSource` (renders another
        GPU pipeline already holds on the device), or a bundle ``SourceSpec``.
    cameras: {view: Camera}, needed when any source is rendered here.
    method_pres: {method: source} for methods scored against their own
        pre-removal source instead of ``pre`` (same kinds as ``pre``).
    target: as scene.toml's [target] (`.target`): {"masks": {view: (H, W) bool},
        "indices": (K,) int or (N,) bool over pre's Gaussians, "box": {min, max} or
        {centre, size, rotation}}; then ``masks`` may be empty, every camera is an
        evaluation view and views without a mask get the target's rendered mask.
    """
    check_names("scene", [name])
    check_names("method", list(methods or {}), reserved=RESERVED_METHOD_NAMES)
    spec = None
    if target is not None:
        from .target import target_from_objects

        if cameras is None:
            raise InputError(f"scene {name!r}: a target needs cameras (every camera is an evaluation view)")
        views = sorted(cameras)
        spec = target_from_objects(target, views)
        masks = {**(masks or {}), **(spec.masks or {})}
    else:
        views = sorted(masks or {})
    check_names("view", views)
    for v in views:
        if v not in masks:  # a [target] view whose mask is rendered
            continue
        m = np.asarray(masks[v])
        if m.ndim != 2 or m.size == 0:
            raise InputError(f"scene {name!r}: the mask of view {v!r} has shape {m.shape}; expected (H, W)")
        cam = (cameras or {}).get(v)
        if cam is not None and m.shape != (cam.height, cam.width):
            raise InputError(f"scene {name!r}: the mask of view {v!r} is {m.shape[1]}x{m.shape[0]}, its camera "
                             f"is {cam.width}x{cam.height}")
    if not views:
        raise InputError(f"scene {name!r}: no views (masks is empty)")
    if not methods:
        raise InputError(f"scene {name!r}: no methods")
    unknown = sorted(set(method_pres or {}) - set(methods))
    if unknown:
        raise InputError(f"scene {name!r}: method_pres names methods that are not given: {unknown}")
    missing = [v for v in views if cameras is not None and v not in cameras]
    if missing:
        raise InputError(f"scene {name!r}: views without a camera: {missing[:5]}")
    sources = [("pre", pre), ("reference", reference), *methods.items(),
               *((f"pre of {m}", s) for m, s in (method_pres or {}).items())]
    for role, source in sources:
        _check_device_views(name, role, source, masks, views)
    bundle = Bundle(root=Path("."), name=name, prompt=prompt, views=views,
                  cameras=None if cameras is None else {v: cameras[v] for v in views},
                  masks={v: np.asarray(masks[v]) for v in views if v in masks}, pre=pre, reference=reference,
                  methods=dict(methods),
                  options=BundleOptions(background=tuple(background), depth=depth, reference_free=reference_free),
                  layout="objects", method_pres=dict(method_pres or {}), target=spec)
    check_bundle_names(bundle)  # the names scene.toml and METHOD=FOLDER accept, no others
    return bundle


def is_from_objects(bundle: Bundle) -> bool:
    """True when some source or mask is an object rather than a file spec."""
    from .model import SourceSpec

    specs = [bundle.pre, bundle.reference, *bundle.methods.values(), *bundle.method_pres.values()]
    return not (all(s is None or isinstance(s, SourceSpec) for s in specs)
                and not any(isinstance(m, np.ndarray) for m in bundle.masks.values()))


def _check_device_views(scene: str, role: str, source, masks: dict, views: list) -> None:
    """Renders handed over in memory (a DeviceViewsSource) must have every view, at its mask's size:
    said here, by view, rather than by a kernel's index later."""
    if getattr(source, "kind", None) != "device":
        return
    missing = [v for v in views if v not in source.views]
    if missing:
        raise InputError(f"scene {scene!r}: {role} has no render for view(s) {missing[:5]}")
    for v in views:
        h, w = np.asarray(masks[v]).shape
        item = source.views[v]
        if hasattr(item, "height"):
            shapes = {"render": (item.height, item.width)}
        else:
            rgb, depth = item
            shapes = {"rgb": tuple(np.shape(rgb)[:2]) if np.ndim(rgb) == 3 and np.shape(rgb)[2] == 3 else np.shape(rgb)}
            if depth is not None:
                shapes["depth"] = (depth.height, depth.width) if hasattr(depth, "height") else np.shape(depth)
        for what, shape in shapes.items():
            if tuple(shape) != (h, w):
                raise InputError(f"scene {scene!r}: {role}'s {what} of view {v!r} has shape {tuple(shape)}; its "
                                 f"mask is ({h}, {w}) (rgb must be (H, W, 3), depth (H, W))")
