"""r360gpu: a GPU-portable evaluator for object removal in 3D Gaussian Splatting.

Data flows one way through the sub-packages:
``io`` (load) -> ``render`` -> ``probes`` -> ``metrics`` (measure)
-> ``aggregate`` -> ``report``.  ``gpu`` and ``kernels`` are the device layer
used by ``render`` and ``metrics``; ``cli`` drives everything.
"""
from __future__ import annotations

__version__ = "0.1.0"
