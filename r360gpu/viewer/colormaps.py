"""Colour maps of the depth and |dD| overlays as 256-entry lookup tables.

Each map is given by 11 control colours at 0, 0.1, ..., 1 (sRGB in [0, 1];
turbo, viridis and inferno are samples of the published maps of the same
names) and linearly interpolated to :data:`LUT_SIZE` entries.  The overlay
shader indexes the table with ``round(clamp(x, 0, 1) * 255)``; the numpy
twin :func:`apply` does the same, so tests can compare the two exactly.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

LUT_SIZE = 256

_CONTROL = {
    "turbo": [(0.19, 0.072, 0.232), (0.27, 0.349, 0.796), (0.244, 0.609, 0.997), (0.098, 0.837, 0.803),
              (0.276, 0.971, 0.517), (0.644, 0.99, 0.234), (0.883, 0.866, 0.217), (0.996, 0.643, 0.192),
              (0.941, 0.356, 0.07), (0.765, 0.144, 0.01), (0.48, 0.016, 0.011)],
    "viridis": [(0.267, 0.005, 0.329), (0.283, 0.141, 0.458), (0.254, 0.265, 0.53), (0.207, 0.372, 0.553),
                (0.164, 0.471, 0.558), (0.128, 0.567, 0.551), (0.135, 0.659, 0.518), (0.267, 0.749, 0.441),
                (0.478, 0.821, 0.318), (0.741, 0.873, 0.15), (0.993, 0.906, 0.144)],
    "inferno": [(0.001, 0.0, 0.014), (0.087, 0.045, 0.225), (0.258, 0.039, 0.406), (0.416, 0.09, 0.433),
                (0.578, 0.148, 0.404), (0.736, 0.216, 0.33), (0.865, 0.317, 0.226), (0.955, 0.469, 0.1),
                (0.988, 0.645, 0.04), (0.964, 0.844, 0.273), (0.988, 0.998, 0.645)],
    "gray": [(v, v, v) for v in np.linspace(0.0, 1.0, 11)],
}

NAMES = tuple(_CONTROL)


@lru_cache(maxsize=None)
def lut(name: str) -> np.ndarray:
    """(LUT_SIZE, 4) float32 RGBA table of map ``name`` (alpha 1); read-only."""
    if name not in _CONTROL:
        raise ValueError(f"unknown colour map {name!r}; choose one of {NAMES}")
    ctrl = np.asarray(_CONTROL[name], dtype=np.float64)
    x = np.linspace(0.0, 1.0, LUT_SIZE)
    xs = np.linspace(0.0, 1.0, len(ctrl))
    table = np.ones((LUT_SIZE, 4), np.float32)
    for c in range(3):
        table[:, c] = np.interp(x, xs, ctrl[:, c])
    table.flags.writeable = False
    return table


def apply(name: str, values: np.ndarray) -> np.ndarray:
    """Colours (..., 3) float32 of ``values`` in [0, 1] (clamped), as the shader indexes the table."""
    v = np.clip(np.nan_to_num(np.asarray(values, dtype=np.float32), nan=0.0), 0.0, 1.0)
    idx = np.floor(v * np.float32(LUT_SIZE - 1) + np.float32(0.5)).astype(np.int64)
    return lut(name)[idx, :3]
