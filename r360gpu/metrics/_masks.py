"""Input normalisation shared by the mask-based metrics (semantic, structural,
sensitivity).  Bad shapes or dtypes become :class:`~r360gpu.errors.InputError`
naming the view, before anything reaches the GPU kernels."""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def where(view: str) -> str:
    """Prefix for error messages: ``"view 00012: "`` or ``""``."""
    return f"view {view}: " if view else ""


def binary(arr, what: str, view: str = "") -> np.ndarray:
    """bool array from a bool / integer / float array (non-zero = inside)."""
    a = np.asarray(arr)
    if a.dtype == np.bool_:
        return a
    if np.issubdtype(a.dtype, np.floating):
        if np.isnan(a).any():
            raise InputError(f"{where(view)}{what} contains NaN (a binary mask is expected)")
        return a != 0
    if np.issubdtype(a.dtype, np.integer):
        return a != 0
    raise InputError(f"{where(view)}{what} must be a bool or numeric mask, got dtype {a.dtype}")


def target_mask(mask, view: str = "") -> np.ndarray:
    """The target mask M^v as bool (H, W); non-zero = target."""
    if mask is None:
        raise InputError(f"{where(view)}no target mask given")
    m = binary(mask, "target mask", view)
    if m.ndim != 2 or m.shape[0] < 1 or m.shape[1] < 1:
        raise InputError(f"{where(view)}target mask must be a non-empty 2-D (H, W) array, got shape {m.shape}")
    return m


def mask_stack(masks, size: tuple[int, int], what: str, view: str = "") -> np.ndarray:
    """bool (K, H, W) from a probe result or an array.

    ``masks``: a :class:`~r360gpu.probes.base.SemanticPrediction` or
    :class:`~r360gpu.probes.base.MaskSet` (its ``.masks``), a (K, H, W) stack,
    a single (H, W) mask (K = 1) or None (K = 0, no masks).  ``size`` is the
    (H, W) of the target mask; any other size is an InputError.
    """
    h, w = size
    if masks is None:
        return np.zeros((0, h, w), bool)
    arr = getattr(masks, "masks", masks)
    m = binary(arr, what, view)
    if m.ndim == 2:
        m = m[None]
    if m.ndim != 3:
        raise InputError(f"{where(view)}{what} must be (K, H, W) or (H, W), got shape {m.shape}")
    if m.shape[1:] != (h, w):
        raise InputError(
            f"{where(view)}{what} are {m.shape[1]}x{m.shape[2]} but the target mask is {h}x{w} (H x W)"
        )
    return m


def probe_name(*results) -> str:
    """The ``probe`` name carried by the first probe result that has one, else ``""``."""
    for r in results:
        name = getattr(r, "probe", "")
        if name:
            return str(name)
    return ""
