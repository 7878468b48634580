"""r360gpu: a GPU-portable evaluator for object removal in 3D Gaussian Splatting.

Data flows one way through the sub-packages:
``io`` (load) -> ``render`` -> ``probes`` -> ``metrics`` (measure)
-> ``aggregate`` -> ``report``; ``pipeline`` runs the stages per view.  ``gpu`` and ``kernels`` are the device layer
used by ``render`` and ``metrics``; ``cli`` drives everything.

The names exported here: `evaluate` with `EvaluateOptions` (score scenes),
`load_bundle` / `check_bundle` (read or validate a scene folder),
`scene_from_objects` and `DeviceViewsSource` (scenes held in memory or on a GPU).
"""
from __future__ import annotations

__version__ = "0.1.0"

__all__ = ["evaluate", "scene_from_objects", "EvaluateOptions", "DeviceViewsSource", "load_bundle", "check_bundle",
           "__version__"]


def __getattr__(name):
    # Imported lazily so `import r360gpu` stays light (no wgpu, scipy, cv2).
    if name in ("evaluate", "EvaluateOptions"):
        from . import pipeline

        return getattr(pipeline, name)
    if name in ("scene_from_objects", "load_bundle", "check_bundle"):
        from . import bundle

        return getattr(bundle, name)
    if name == "DeviceViewsSource":
        from .render.sources import DeviceViewsSource

        return DeviceViewsSource
    raise AttributeError(f"module 'r360gpu' has no attribute {name!r}")
