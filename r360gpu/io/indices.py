"""Gaussian indices given by a user (``[target].indices``, ``scene_from_objects(target={"indices": ...})``)
checked before they reach numpy: whole numbers or booleans in a flat array, never strings, sets or
ragged lists.  Defined here, beside the loaders, so that a bundle can check them without importing
:mod:`r360gpu.lift`."""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def index_array(value, where: str) -> np.ndarray:
    """``value`` as a 1-D int64 array of indices, or a 1-D bool array (one entry per Gaussian);
    InputError naming ``where`` for anything else (text, a set or dict, a ragged or nested list,
    fractional or non-finite numbers)."""
    if isinstance(value, (str, bytes, set, frozenset, dict)):
        raise InputError(f"{where}: target indices must be a list or array of Gaussian indices (integers) or "
                         f"one boolean per Gaussian, got a {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting numpy refuses
        raise InputError(f"{where}: target indices must be a flat list of integers (got a ragged list)") from None
    if arr.dtype.kind not in "biuf":
        raise InputError(f"{where}: target indices must be integers or booleans, got {arr.dtype} values "
                         f"(e.g. {arr.reshape(-1)[:1].tolist() if arr.size else value!r})")
    if arr.ndim != 1:
        raise InputError(f"{where}: target indices must be a flat (1-D) array, got shape {arr.shape}")
    if arr.dtype.kind == "b":
        return arr
    if arr.dtype.kind == "f" and arr.size and (not np.isfinite(arr).all() or np.any(arr != np.round(arr))):
        raise InputError(f"{where}: target indices must be whole numbers")
    # beyond int64 a cast wraps (uint64) or is undefined (float): refused here, with the value given
    limit = np.iinfo(np.int64).max
    huge = (arr[arr > limit] if arr.dtype.kind == "u" else
            arr[np.abs(arr.astype(np.float64)) >= 2.0 ** 63] if arr.dtype.kind == "f" else arr[:0])
    if huge.size:
        raise InputError(f"{where}: {huge.size} target indices too large to be a Gaussian's index (e.g. "
                         f"{huge[0].item()!r}); are they indices into pre's Gaussians?")
    return arr.astype(np.int64)
