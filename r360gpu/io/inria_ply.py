"""INRIA 3DGS ``point_cloud.ply``: reader and writer.

The ``vertex`` element holds one Gaussian per record with the raw training
parameters:

* ``x y z``                      mean (world)
* ``nx ny nz``                   optional, unused (INRIA writes zeros)
* ``f_dc_0..2``                  SH DC coefficient per channel (R, G, B)
* ``f_rest_0..M-1``              higher-order SH, **channel-major**: the
  (K-1) coefficients of R, then of G, then of B; M = 3*(K-1) in
  {0, 9, 24, 45} for SH degree 0..3
* ``opacity``                    logit (-> sigmoid)
* ``scale_0..2``                 log of the scales (-> exp)
* ``rot_0..3``                   quaternion (w, x, y, z), unnormalised (-> normalised)

Any PLY encoding and scalar type is accepted; properties and elements beyond
these are ignored with one R360Warning naming them.
"""
from __future__ import annotations

import os
import re
import warnings

import numpy as np
from numpy.lib.recfunctions import structured_to_unstructured

from ..errors import InputError, R360Warning
from .gaussians import Gaussians, build_gaussians
from .ply import PlyData, read_ply, write_ply
from .sh import sh_coeff_count

_REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
             "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
_OPTIONAL = ["nx", "ny", "nz"]
#: The vertex property r360gpu's residual PLYs add (:func:`r360gpu.lift.residuals.write_residual_ply`);
#: read back without a warning, and not part of the Gaussians.
RESIDUAL = "residual"
#: The vertex property of r360gpu's lifted-target PLYs (1: the Gaussian is the target); read back likewise.
TARGET = "target"
_F_REST = re.compile(r"f_rest_(\d+)$")
_VALID_REST_COUNTS = {0: 0, 9: 1, 24: 2, 45: 3}

# Opacities are stored as logits; 0 and 1 have none, so the writer clips to the
# nearest float32 values strictly inside (0, 1).
_OPACITY_LO = float(np.finfo(np.float32).tiny)
_OPACITY_HI = float(np.nextafter(np.float32(1.0), np.float32(0.0)))


def is_inria_ply(ply: PlyData) -> bool:
    """True if the header has a ``vertex`` element with the 3DGS position and rotation properties."""
    el = ply.element("vertex")
    return el is not None and {"x", "rot_0"} <= set(el.property_names())


def load_inria_ply(path: str | os.PathLike) -> Gaussians:
    """Read an INRIA 3DGS .ply (any PLY encoding); see the module docstring."""
    return gaussians_from_inria_ply(read_ply(path))


def check_inria_header(ply: PlyData) -> list[int]:
    """Every check of an INRIA 3DGS PLY that its header decides (InputError naming the file);
    returns the f_rest indices.  :func:`gaussians_from_inria_ply` and ``r360gpu check`` both run it."""
    el = ply.element("vertex")
    if el is None:
        raise InputError("PLY file has no 'vertex' element (not a Gaussian-splat PLY)", ply.path)
    names = el.property_names()
    missing = [p for p in _REQUIRED if p not in names]
    if missing:
        raise InputError(f"missing required 3DGS properties: {', '.join(missing)}", ply.path)
    if el.has_lists:
        raise InputError("the 'vertex' element has list properties (a mesh, not Gaussians)", ply.path)
    rest_idx = sorted(int(m.group(1)) for m in map(_F_REST.match, names) if m)
    if rest_idx != list(range(len(rest_idx))):
        raise InputError("f_rest_* properties are not numbered 0..M-1 without gaps", ply.path)
    if len(rest_idx) not in _VALID_REST_COUNTS:
        raise InputError(
            f"{len(rest_idx)} f_rest_* properties; 3DGS files have 0, 9, 24 or 45 "
            f"(SH degree 0..3)", ply.path)
    return rest_idx


def gaussians_from_inria_ply(ply: PlyData) -> Gaussians:
    """Decode an already parsed INRIA 3DGS PLY (drop policy of :func:`build_gaussians`)."""
    rest_idx = check_inria_header(ply)
    el = ply.element("vertex")
    names = el.property_names()
    _warn_ignored(ply, known=set(_REQUIRED) | set(_OPTIONAL) | {f"f_rest_{i}" for i in rest_idx} | {RESIDUAL, TARGET})

    v = ply.arrays["vertex"]
    n = el.count

    def cols(*keys: str, dtype=np.float32) -> np.ndarray:
        # (n, len(keys)); a multi-field view copied at once, far faster than column by column.
        if not keys:
            return np.zeros((n, 0), dtype)
        with np.errstate(over="ignore"):  # double values beyond float32 become Inf (then dropped)
            return structured_to_unstructured(v[list(keys)], dtype=dtype)

    k = sh_coeff_count(_VALID_REST_COUNTS[len(rest_idx)])
    sh = np.empty((n, k, 3), np.float32)
    sh[:, 0, :] = cols("f_dc_0", "f_dc_1", "f_dc_2")
    rest = cols(*(f"f_rest_{i}" for i in rest_idx)).reshape(n, 3, k - 1)
    sh[:, 1:, :] = rest.transpose(0, 2, 1)
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        scales = np.exp(cols("scale_0", "scale_1", "scale_2", dtype=np.float64))
        opacities = 1.0 / (1.0 + np.exp(-v["opacity"].astype(np.float64)))
    quats = cols("rot_0", "rot_1", "rot_2", "rot_3", dtype=np.float64)
    return build_gaussians(cols("x", "y", "z"), scales, quats, opacities, sh, source=ply.path)


def _warn_ignored(ply: PlyData, known: set[str]) -> None:
    extra = [p for p in ply.element("vertex").property_names() if p not in known]
    other = [e.name for e in ply.elements if e.name != "vertex"]
    parts = []
    if extra:
        shown = ", ".join(extra[:8]) + (f" and {len(extra) - 8} more" if len(extra) > 8 else "")
        parts.append(f"vertex properties {shown}")
    if other:
        parts.append(f"elements {', '.join(other)}")
    if parts:
        warnings.warn(f"{ply.path}: ignoring {'; '.join(parts)} (not part of the 3DGS layout)",
                      R360Warning, stacklevel=4)


def save_ply(path: str | os.PathLike, gaussians: Gaussians, format: str = "binary_little_endian") -> None:
    """Write ``gaussians`` as an INRIA 3DGS .ply (atomically), all properties float32.

    Inverse of :func:`load_inria_ply`: log-scales, logit opacities (opacities
    are first clipped into the open interval (0, 1): exactly 0 or 1 come back
    as ~1.2e-38 and 1 - 6e-8), f_rest channel-major, ``nx ny nz`` zeros.
    format: 'binary_little_endian' (default, what INRIA writes),
    'binary_big_endian' or 'ascii'.
    """
    write_ply(path, [("vertex", vertex_records(gaussians))], format=format)


def vertex_records(gaussians: Gaussians) -> np.ndarray:
    """(N,) structured float32 array of the INRIA 3DGS vertex properties of ``gaussians`` (as
    :func:`save_ply` writes them)."""
    g = gaussians
    n, k = g.n, g.sh.shape[1]
    rest_names = [f"f_rest_{i}" for i in range(3 * (k - 1))]
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", *rest_names,
             "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    rec = np.zeros(n, dtype=[(name, "<f4") for name in names])
    for i, c in enumerate("xyz"):
        rec[c] = g.means[:, i]
    for c in range(3):
        rec[f"f_dc_{c}"] = g.sh[:, 0, c]
    rest = g.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, -1)  # channel-major
    for i, name in enumerate(rest_names):
        rec[name] = rest[:, i]
    op = np.clip(g.opacities.astype(np.float64), _OPACITY_LO, _OPACITY_HI)
    rec["opacity"] = np.log(op) - np.log1p(-op)
    log_s = np.log(g.scales.astype(np.float64))
    for i in range(3):
        rec[f"scale_{i}"] = log_s[:, i]
        rec[f"rot_{i}"] = g.quats[:, i]
    rec["rot_3"] = g.quats[:, 3]
    return rec


def write_labelled_ply(path: str | os.PathLike, gaussians: Gaussians, prop: str, values: np.ndarray,
                       missing, dtype: str, *, source=None) -> None:
    """Write ``gaussians`` as an INRIA 3DGS PLY (atomically) with the vertex property ``prop`` holding
    ``values`` (N,) as ``dtype``, one vertex per row of the file they were read from.

    ``source`` (the file's path), when it is an INRIA PLY of as many rows, is copied vertex for vertex
    with every property it has (a ``my_label`` stays; an old ``prop`` is replaced); otherwise the
    Gaussians' own properties.  A row the loader dropped (invalid values, `Gaussians.rows`) keeps its
    place with ``prop`` = ``missing`` (and, when not copied, NaN properties).
    """
    from numpy.lib import recfunctions

    v = np.asarray(values)
    if v.shape != (gaussians.n,):
        raise ValueError(f"{prop} has shape {v.shape}, the scene {gaussians.n} Gaussians")
    full = np.full(gaussians.n_file, missing, dtype)
    full[gaussians.rows] = v
    vert = None
    if source is not None and str(source).lower().endswith(".ply") and os.path.isfile(source):
        ply = read_ply(source)
        if is_inria_ply(ply) and len(ply.arrays["vertex"]) == gaussians.n_file:
            vert = ply.arrays["vertex"]
            if prop in (vert.dtype.names or ()):  # a labelled PLY given again: this run's values
                vert = recfunctions.drop_fields(vert, prop, usemask=False)
    if vert is None:
        own = vertex_records(gaussians)
        vert = np.full(gaussians.n_file, np.nan, own.dtype)
        vert[gaussians.rows] = own
    vert = recfunctions.append_fields(vert, prop, full, dtypes=dtype, usemask=False)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    write_ply(path, [("vertex", vert)])
