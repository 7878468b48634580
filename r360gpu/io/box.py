"""A 3D box, axis-aligned or oriented: a target given by its extent (scene.toml ``[target].box``).

Read by the bundle loader and used by :mod:`r360gpu.lift` to select pre's Gaussians; defined
here, beside the other geometry the loaders produce, so that loading does not import lifting.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from numbers import Real

import numpy as np

from ..errors import InputError
from .rotation import quat_to_rotmat


@dataclass(frozen=True)
class Box:
    """An oriented box: ``centre`` (3,), ``half`` (3,) half-extents along the box's axes,
    ``rotation`` (3, 3) whose columns are the box's axes in world coordinates."""

    centre: np.ndarray
    half: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    @classmethod
    def from_table(cls, table: dict, *, where: str = "box") -> "Box":
        """A box from ``{min, max}`` (axis-aligned) or ``{centre, size[, rotation]}`` where rotation is a
        3x3 matrix (columns = box axes) or a (w, x, y, z) quaternion."""
        def vec(key, k=3):
            value = table[key]
            # numbers only: numpy would read "1.5" and True as 1.5 and 1.0, and flatten [[x, y, z]]
            if isinstance(value, (list, tuple)):
                numbers = all(isinstance(x, Real) and not isinstance(x, (bool, np.bool_)) for x in value)
            else:
                numbers = isinstance(value, np.ndarray) and value.dtype.kind in "iuf"
            if not numbers or np.ndim(value) != 1 or len(value) != k:
                raise InputError(f"{where}.{key} must be {k} finite numbers, got {value!r}")
            v = np.asarray(value, np.float64)
            if not np.isfinite(v).all():
                raise InputError(f"{where}.{key} must be {k} finite numbers, got {value!r}")
            return v

        if not isinstance(table, dict):
            raise InputError(f"{where} must be a table ({{min = [...], max = [...]}} or {{centre, size}})")
        keys = set(table)
        centre_key = "centre" if "centre" in keys else "center"
        if keys == {"min", "max"}:
            lo, hi = vec("min"), vec("max")
            if np.any(hi <= lo):
                raise InputError(f"{where}: max must be > min on every axis (a box of no volume holds no "
                                 f"Gaussian), got min={lo.tolist()} max={hi.tolist()}")
            return cls(0.5 * (lo + hi), 0.5 * (hi - lo))
        if centre_key in keys and "size" in keys and keys <= {centre_key, "size", "rotation"}:
            size = vec("size")
            if np.any(size <= 0):
                raise InputError(f"{where}.size must be > 0 on every axis (a box of no volume holds no "
                                 f"Gaussian), got {size.tolist()}")
            rot = np.eye(3)
            if "rotation" in table:
                try:
                    r = np.asarray(table["rotation"])
                    if r.dtype.kind not in "iuf":  # text or booleans, which a float cast would read
                        raise TypeError
                    r = r.astype(np.float64)
                except (TypeError, ValueError):  # text, or a ragged matrix numpy refuses
                    raise InputError(f"{where}.rotation must be a 3x3 rotation matrix or a (w, x, y, z) "
                                     f"quaternion of numbers, got {table['rotation']!r}") from None
                if r.shape == (4,):
                    if not np.isfinite(r).all() or np.linalg.norm(r) == 0:
                        raise InputError(f"{where}.rotation quaternion must be finite and non-zero")
                    rot = quat_to_rotmat(r)  # (w, x, y, z): the order io.rotation defines
                elif r.shape == (3, 3) and np.isfinite(r).all() and np.allclose(r.T @ r, np.eye(3), atol=1e-4):
                    rot = r
                else:
                    raise InputError(f"{where}.rotation must be a 3x3 rotation matrix or a (w, x, y, z) quaternion")
            return cls(vec(centre_key), 0.5 * size, rot)
        raise InputError(f"{where} needs min and max, or centre and size (and optionally rotation); "
                         f"got keys {', '.join(sorted(keys)) or 'none'}")

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: points (N, 3) inside the box (boundary included)."""
        local = (np.asarray(points, np.float64) - self.centre) @ self.rotation
        return np.all(np.abs(local) <= self.half + 1e-12, axis=1)
