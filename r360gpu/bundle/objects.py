"""Scenes built from in-memory objects (no files): library use from another pipeline."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from .model import Bundle, BundleOptions


def scene_from_objects(name: str, prompt: str, masks: dict, pre, methods: dict, *, reference=None,
                       cameras: dict | None = None, background=(0.0, 0.0, 0.0), depth: str = "expected",
                       reference_free: bool = False, method_pres: dict | None = None, target: dict | None = None
                       ) -> Bundle:
    """A scene to pass to :func:`r360gpu.evaluate` without files.

    masks: {view: bool (H, W) target mask}; the keys are the evaluation views.
    pre, reference, methods[...]: each a :class:`~r360gpu.io.Gaussians`
        (rendered at ``cameras``), a
        :class:`~r360gpu.render.sources.DeviceViewsSource` (renders another
        GPU pipeline already holds on the device), or a bundle ``SourceSpec``.
    cameras: {view: Camera}, needed when any source is rendered here.
    method_pres: {method: source} for methods scored against their own
        pre-removal source instead of ``pre`` (same kinds as ``pre``).
    target: as scene.toml's [target] (:mod:`.target`): {"masks": {view: (H, W) bool},
        "indices": (K,) int or (N,) bool over pre's Gaussians, "box": {min, max} or
        {centre, size, rotation}}; then ``masks`` may be empty, every camera is an
        evaluation view and views without a mask get the target's rendered mask.
    """
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
    return Bundle(root=Path("."), name=name, prompt=prompt, views=views,
                  cameras=None if cameras is None else {v: cameras[v] for v in views},
                  masks={v: np.asarray(masks[v]) for v in views if v in masks}, pre=pre, reference=reference,
                  methods=dict(methods),
                  options=BundleOptions(background=tuple(background), depth=depth, reference_free=reference_free),
                  layout="objects", method_pres=dict(method_pres or {}), target=spec)


def is_from_objects(bundle: Bundle) -> bool:
    """True when some source or mask is an object rather than a file spec."""
    from .model import SourceSpec

    specs = [bundle.pre, bundle.reference, *bundle.methods.values(), *bundle.method_pres.values()]
    return not (all(s is None or isinstance(s, SourceSpec) for s in specs)
                and not any(isinstance(m, np.ndarray) for m in bundle.masks.values()))
