"""The in-memory Gaussian-splat scene every loader produces and the renderer consumes.

Conventions (defined here, once):

* ``means``      (N, 3) float32, world coordinates (the scene's own units).
* ``scales``     (N, 3) float32, *linear* standard deviations along the
  Gaussian's local axes (already ``exp``'d from the log-scales of a 3DGS
  checkpoint), finite and > 0.
* ``quats``      (N, 4) float32, unit quaternions in **(w, x, y, z)** order
  (INRIA ``rot_0..rot_3``), rotating local axes to world.  The sign is not
  canonicalised (q and -q are the same rotation).
* ``opacities``  (N,) float32, already passed through the sigmoid, in
  **[0, 1]** (the closed interval: a float32 sigmoid saturates to exactly 0
  or 1 for large logits, and 8-bit formats store 0 and 255).
* ``sh``         (N, K, 3) float32 spherical-harmonics coefficients,
  ``K = (sh_degree + 1)**2``, coefficient-major; ``sh[:, 0, :]`` is the DC
  term per RGB channel.  Colour = ``max(SH_eval(dir) + 0.5, 0)``; the basis
  and its constants are in :mod:`r360gpu.io.sh`.

All arrays are C-contiguous and read-only views (the dataclass is frozen; use
:meth:`Gaussians.subset`, :meth:`Gaussians.concat`,
:meth:`Gaussians.with_sh_degree` to derive new scenes).

Bad-input policy for loaders (:func:`build_gaussians`, used by every format):
structural problems of a file (truncated, wrong counts, missing properties)
are an :class:`~r360gpu.errors.InputError`; individual Gaussians with
NaN/Inf in any parameter, a zero quaternion, a non-positive scale or an
opacity outside [0, 1] are dropped, and the drop is reported in ONE
:class:`~r360gpu.errors.R360Warning` with counts per reason.  A file left
with no Gaussian at all is an InputError.  The Gaussians kept remember
their rows of the file (:attr:`Gaussians.rows`, :attr:`Gaussians.n_file`):
indices a user gives (``[target].indices``) and indices r360gpu writes
(residuals) are rows of the file as written.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..errors import InputError, R360Warning
from .sh import sh_coeff_count, sh_degree_from_count

# A quaternion whose largest |component| is below this is treated as zero (no rotation defined).
_MIN_QUAT_COMPONENT = 1e-8


def _frozen_f32(arr) -> np.ndarray:
    # A view, so that a caller's array passed through unchanged keeps its writeable flag.
    a = np.ascontiguousarray(arr, dtype=np.float32).view()
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Gaussians:
    """A set of N 3D Gaussians (see the module docstring for every convention).

    The constructor converts the arrays to float32 C-contiguous read-only
    views and validates shapes and values, raising ValueError on violations.
    """

    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray
    #: (N,) int64 row of the file each Gaussian was read from, when a loader dropped invalid rows
    #: (None: Gaussian i is row i); ``file_count`` is then the file's number of rows.  Indices a
    #: user gives and indices r360gpu writes refer to the file's rows (:attr:`rows`, :attr:`n_file`).
    file_rows: np.ndarray | None = None
    file_count: int | None = None

    def __post_init__(self) -> None:
        for name in ("means", "scales", "quats", "opacities", "sh"):
            object.__setattr__(self, name, _frozen_f32(getattr(self, name)))
        self._check_shapes()
        self._check_values()
        if self.file_rows is not None:
            rows = np.asarray(self.file_rows, np.int64)
            count = self.n if self.file_count is None else int(self.file_count)
            if rows.shape != (self.n,) or (rows.size and (rows.min() < 0 or rows.max() >= count)):
                raise ValueError(f"file_rows must be ({self.n},) rows of a file of {count}")
            object.__setattr__(self, "file_rows", rows)

    # -- construction without re-validation (inputs already valid) ----------
    @classmethod
    def _trusted(cls, means, scales, quats, opacities, sh, file_rows=None, file_count=None) -> "Gaussians":
        g = object.__new__(cls)
        for name, arr in zip(("means", "scales", "quats", "opacities", "sh"),
                             (means, scales, quats, opacities, sh)):
            object.__setattr__(g, name, _frozen_f32(arr))
        object.__setattr__(g, "file_rows", file_rows)
        object.__setattr__(g, "file_count", file_count)
        g._check_shapes()
        return g

    def _check_shapes(self) -> None:
        n = self.means.shape[0] if self.means.ndim == 2 else -1
        expect = {
            "means": (n, 3),
            "scales": (n, 3),
            "quats": (n, 4),
            "opacities": (n,),
        }
        if self.means.ndim != 2 or self.means.shape[1] != 3:
            raise ValueError(f"means must have shape (N, 3), got {self.means.shape}")
        for name, shape in expect.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {getattr(self, name).shape}")
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3:
            raise ValueError(f"sh must have shape ({n}, K, 3), got {self.sh.shape}")
        sh_degree_from_count(self.sh.shape[1])

    def _check_values(self) -> None:
        bad = _bad_counts(self.means, self.scales, self.quats, self.opacities, self.sh, normalised=True)
        if bad:
            raise ValueError("invalid Gaussians: " + _describe(bad))

    # -- properties ----------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of Gaussians N."""
        return int(self.means.shape[0])

    def __len__(self) -> int:
        return self.n

    @property
    def rows(self) -> np.ndarray:
        """(N,) int64: the file row of each Gaussian (0..N-1 when no row was dropped)."""
        return np.arange(self.n, dtype=np.int64) if self.file_rows is None else self.file_rows

    @property
    def n_file(self) -> int:
        """Rows of the file the Gaussians were read from (N when no row was dropped)."""
        return self.n if self.file_count is None else int(self.file_count)

    @property
    def sh_degree(self) -> int:
        """SH degree 0..3, from ``K = sh.shape[1] = (degree + 1)**2``."""
        return sh_degree_from_count(self.sh.shape[1])

    def content_digest(self) -> str:
        """A hex digest of every value (shapes included): equal for equal Gaussians.

        Computed anew on each call (the arrays may be read-only views of a
        caller's array that the caller can still change): 0.39 s per million
        Gaussians of SH degree 3 on a 2-core machine (blake2b over 236 MB).
        """
        import hashlib

        h = hashlib.blake2b(digest_size=16)
        for a in (self.means, self.scales, self.quats, self.opacities, self.sh):
            h.update(str(a.shape).encode())
            h.update(np.ascontiguousarray(a).data)
        return h.hexdigest()

    # -- derivation ----------------------------------------------------------
    def subset(self, selection) -> "Gaussians":
        """The Gaussians picked by a boolean mask (N,) or an integer index array."""
        sel = np.asarray(selection)
        if sel.dtype == bool and sel.shape != (self.n,):
            raise ValueError(f"boolean mask must have shape ({self.n},), got {sel.shape}")
        if sel.dtype != bool and not np.issubdtype(sel.dtype, np.integer):
            raise ValueError(f"selection must be a boolean mask or integer indices, got dtype {sel.dtype}")
        return Gaussians._trusted(self.means[sel], self.scales[sel], self.quats[sel],
                                  self.opacities[sel], self.sh[sel], self.rows[sel], self.n_file)

    def with_sh_degree(self, degree: int) -> "Gaussians":
        """The same Gaussians with SH truncated to, or zero-padded up to, ``degree``."""
        k = sh_coeff_count(degree)
        if k <= self.sh.shape[1]:
            sh = self.sh[:, :k, :]
        else:
            sh = np.zeros((self.n, k, 3), np.float32)
            sh[:, : self.sh.shape[1], :] = self.sh
        return Gaussians._trusted(self.means, self.scales, self.quats, self.opacities, sh, self.file_rows,
                                  self.file_count)

    @staticmethod
    def concat(parts: Sequence["Gaussians"]) -> "Gaussians":
        """All Gaussians of ``parts`` in order; SH is zero-padded to the highest degree."""
        parts = list(parts)
        if not parts:
            raise ValueError("concat needs at least one Gaussians")
        degree = max(p.sh_degree for p in parts)
        parts = [p.with_sh_degree(degree) for p in parts]
        return Gaussians._trusted(*(np.concatenate([getattr(p, f) for p in parts])
                                    for f in ("means", "scales", "quats", "opacities", "sh")))

    def __repr__(self) -> str:
        return f"Gaussians(n={self.n}, sh_degree={self.sh_degree})"


def _bad_counts(means, scales, quats, opacities, sh, *, normalised: bool) -> dict[str, np.ndarray]:
    """Boolean masks (N,) of Gaussians violating each invariant, only non-empty ones."""
    nonfinite = ~np.isfinite(means).all(1) | ~np.isfinite(scales).all(1) | ~np.isfinite(quats).all(1)
    nonfinite |= ~np.isfinite(opacities) | ~np.isfinite(sh).all(axis=(1, 2))
    with np.errstate(invalid="ignore", over="ignore"):
        if normalised:
            qnorm = np.sqrt(np.sum(quats.astype(np.float64) ** 2, axis=1))
            zero_quat = ~nonfinite & ~(np.abs(qnorm - 1.0) <= 1e-3)
        else:
            # Largest |component| rather than the norm: the norm of a finite
            # float64 quaternion can overflow.
            zero_quat = ~nonfinite & ~(np.max(np.abs(quats), axis=1) >= _MIN_QUAT_COMPONENT)
        bad_scale = ~nonfinite & ~(scales > 0).all(1)
        bad_opacity = ~nonfinite & ~((opacities >= 0) & (opacities <= 1))
    masks = {
        "NaN/Inf parameter": nonfinite,
        ("quaternion not unit" if normalised else "zero quaternion"): zero_quat,
        "non-positive scale": bad_scale,
        "opacity outside [0, 1]": bad_opacity,
    }
    return {k: m for k, m in masks.items() if m.any()}


def _describe(bad: dict[str, np.ndarray]) -> str:
    return ", ".join(f"{int(m.sum())} with {reason}" for reason, m in bad.items())


def build_gaussians(means, scales, quats, opacities, sh, *, source: str | os.PathLike) -> Gaussians:
    """Build a valid :class:`Gaussians` from decoded file data, applying the drop policy.

    Arguments are already in the conventions of this module (linear scales,
    sigmoid'd opacities, (w, x, y, z) quaternions not necessarily normalised,
    sh (N, K, 3)); any float dtype.  Quaternions are normalised here (in
    float64).  Gaussians with NaN/Inf anywhere, a zero quaternion, a
    non-positive scale or an opacity outside [0, 1] are dropped with one
    R360Warning naming ``source`` and the counts.  Raises InputError (naming
    ``source``) if no Gaussian is left.
    """
    # Checks run on the float32 values that will be stored: a float64 value can
    # overflow to Inf or underflow to 0 in the cast.
    with np.errstate(over="ignore", under="ignore"):
        means, scales, opacities, sh = (np.asarray(a, dtype=np.float32)
                                        for a in (means, scales, opacities, sh))
    quats = np.asarray(quats, dtype=np.float64)
    n = means.shape[0]
    if n == 0:
        raise InputError("contains no Gaussians", source)
    bad = _bad_counts(means, scales, quats, opacities, sh, normalised=False)
    if bad:
        drop = np.zeros(n, bool)
        for m in bad.values():
            drop |= m
        keep = ~drop
        if not keep.any():
            raise InputError(f"all {n} Gaussians are invalid ({_describe(bad)})", source)
        warnings.warn(
            f"{os.fspath(source)}: dropped {int(drop.sum())} of {n} Gaussians ({_describe(bad)})",
            R360Warning,
            stacklevel=3,
        )
        means, scales, quats, opacities, sh = (a[keep] for a in (means, scales, quats, opacities, sh))
    quats = quats / np.max(np.abs(quats), axis=1, keepdims=True)
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    if bad:  # indices into the file stay the file's: the loaded Gaussians remember their rows
        return Gaussians._trusted(means, scales, quats, opacities, sh, np.flatnonzero(keep).astype(np.int64), n)
    return Gaussians._trusted(means, scales, quats, opacities, sh)


def random_gaussians(n: int, sh_degree: int = 3, seed: int = 0, extent: float = 1.0) -> Gaussians:
    """A reproducible random scene (for tests and synthetic benchmarks).

    Means uniform in [-extent, extent]^3; scales log-uniform in
    [0.01, 0.1] * extent; uniformly random rotations; opacities uniform in
    [0.05, 0.95]; DC coefficients uniform in [-1.5, 1.5], higher-order ones
    uniform in [-0.3, 0.3].
    """
    rng = np.random.default_rng(seed)
    k = sh_coeff_count(sh_degree)
    means = rng.uniform(-extent, extent, (n, 3))
    scales = extent * np.exp(rng.uniform(np.log(0.01), np.log(0.1), (n, 3)))
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    opacities = rng.uniform(0.05, 0.95, n)
    sh = rng.uniform(-0.3, 0.3, (n, k, 3))
    sh[:, 0, :] = rng.uniform(-1.5, 1.5, (n, 3))
    return Gaussians(means, scales, quats, opacities, sh)
