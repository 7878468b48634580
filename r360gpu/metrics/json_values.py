"""Lossless JSON values for the per-view records and results.json (floats, inf and NaN included).

Python writes floats with ``repr``, which round-trips exactly; only the
non-finite values (an identical-image PSNR is +inf) have no JSON form.  They
are written as ``{"__float__": "inf"}`` (or ``"-inf"``, ``"nan"``) so a
strict JSON writer (``allow_nan=False``) accepts the record and
:func:`dec_float` restores the value.
"""
from __future__ import annotations

import math

from ..errors import InputError

_TAG = "__float__"


def enc_float(x: float | None):
    """float -> JSON value (tagged dict for inf / nan); None stays None."""
    if x is None:
        return None
    x = float(x)
    if math.isfinite(x):
        return x
    return {_TAG: "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")}


def dec_float(v, what: str = "value") -> float | None:
    """Inverse of :func:`enc_float`."""
    if v is None:
        return None
    if isinstance(v, dict):
        if set(v) != {_TAG} or v[_TAG] not in ("inf", "-inf", "nan"):
            raise InputError(f"{what}: not a number: {v!r}")
        return float(v[_TAG])
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InputError(f"{what}: expected a number, got {v!r}")
    return float(v)


def enc_tree(obj):
    """Copy of a JSON-like tree (dict / list / tuple / scalars) with every
    float passed through :func:`enc_float`; tuples become lists."""
    if isinstance(obj, dict):
        return {str(k): enc_tree(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [enc_tree(v) for v in obj]
    if isinstance(obj, float):
        return enc_float(obj)
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalars
        return enc_tree(obj.item())
    return obj


def dec_tree(obj):
    """Inverse of :func:`enc_tree` (tagged floats restored; lists stay lists)."""
    if isinstance(obj, dict):
        if set(obj) == {_TAG}:
            return dec_float(obj)
        return {k: dec_tree(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [dec_tree(v) for v in obj]
    return obj


def field(d: dict, key: str, what: str):
    """``d[key]`` or an InputError naming the missing field."""
    if not isinstance(d, dict):
        raise InputError(f"{what}: expected a JSON object, got {type(d).__name__}")
    if key not in d:
        raise InputError(f"{what}: missing field {key!r}")
    return d[key]


def xi_key(xi: float) -> str:
    """A threshold as a JSON object key (``repr`` round-trips exactly)."""
    return repr(float(xi))
