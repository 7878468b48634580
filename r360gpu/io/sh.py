"""Real spherical harmonics as used by 3D Gaussian Splatting (the INRIA convention).

This module is the one place that defines how a Gaussian's colour follows from
its SH coefficients; the renderer must match :func:`sh_to_color` exactly.

Coefficients of one Gaussian form a ``(K, 3)`` array, ``K = (degree + 1)**2``,
coefficient-major: row ``k`` holds basis function ``k`` for the R, G, B
channels, row 0 is the DC (degree-0) term.  The basis functions, in row
order, for a unit view direction ``d = (x, y, z)`` (world coordinates, from
the camera centre towards the Gaussian's mean) are::

    k=0        C0
    k=1..3     -C1*y,  C1*z,  -C1*x
    k=4..8     C2[0]*x*y,  C2[1]*y*z,  C2[2]*(2*z*z - x*x - y*y),
               C2[3]*x*z,  C2[4]*(x*x - y*y)
    k=9..15    C3[0]*y*(3*x*x - y*y),  C3[1]*x*y*z,  C3[2]*y*(4*z*z - x*x - y*y),
               C3[3]*z*(2*z*z - 3*x*x - 3*y*y),  C3[4]*x*(4*z*z - x*x - y*y),
               C3[5]*z*(x*x - y*y),  C3[6]*x*(x*x - 3*y*y)

and the colour is ``max(sum_k basis_k(d) * coeff[k] + 0.5, 0)`` per channel
(clamped below only; values above 1 are left to the compositor, as in INRIA's
``computeColorFromSH``).
"""
from __future__ import annotations

import numpy as np

#: Degree-0 basis constant 1 / (2 sqrt(pi)).
C0 = 0.28209479177387814
#: Degree-1 basis constant sqrt(3) / (2 sqrt(pi)).
C1 = 0.4886025119029199
#: Degree-2 basis constants (row order as in the module docstring).
C2 = (
    1.0925484305920792,
    -1.0925484305920792,
    0.31539156525252005,
    -1.0925484305920792,
    0.5462742152960396,
)
#: Degree-3 basis constants (row order as in the module docstring).
C3 = (
    -0.5900435899266435,
    2.890611442640554,
    -0.4570457994644658,
    0.3731763325901154,
    -0.4570457994644658,
    1.445305721320277,
    -0.5900435899266435,
)

MAX_SH_DEGREE = 3


def sh_coeff_count(degree: int) -> int:
    """Number of SH coefficients per channel, ``(degree + 1)**2``, for degree 0..3."""
    if not 0 <= int(degree) <= MAX_SH_DEGREE or int(degree) != degree:
        raise ValueError(f"SH degree must be an integer in 0..{MAX_SH_DEGREE}, got {degree!r}")
    return (int(degree) + 1) ** 2


def sh_degree_from_count(count: int) -> int:
    """Inverse of :func:`sh_coeff_count`; ValueError if ``count`` is not 1, 4, 9 or 16."""
    for degree in range(MAX_SH_DEGREE + 1):
        if sh_coeff_count(degree) == count:
            return degree
    raise ValueError(f"{count} SH coefficients per channel is not (degree+1)^2 for a degree in 0..3")


def sh_basis(dirs: np.ndarray, degree: int) -> np.ndarray:
    """SH basis functions evaluated at unit directions.

    dirs: (N, 3) unit vectors (any float dtype).  Returns (N, K) float64 with
    ``K = (degree + 1)**2``, columns in the row order of the module docstring.
    """
    d = np.asarray(dirs, dtype=np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    cols = [np.full_like(x, C0)]
    if degree >= 1:
        cols += [-C1 * y, C1 * z, -C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        cols += [
            C2[0] * x * y,
            C2[1] * y * z,
            C2[2] * (2.0 * zz - xx - yy),
            C2[3] * x * z,
            C2[4] * (xx - yy),
        ]
    if degree >= 3:
        cols += [
            C3[0] * y * (3.0 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4.0 * zz - xx - yy),
            C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            C3[4] * x * (4.0 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3.0 * yy),
        ]
    sh_coeff_count(degree)  # validates degree
    return np.stack(cols, axis=1)


def sh_to_color(sh: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Reference colour of Gaussians seen along ``dirs`` (the renderer's contract).

    sh: (N, K, 3) coefficients (coefficient-major, see module docstring).
    dirs: (N, 3) directions from the camera centre to each Gaussian's mean; they
    are normalised here (a zero direction gives the DC colour only).
    Returns (N, 3) float64 RGB, ``max(SH(d) + 0.5, 0)``.
    """
    sh = np.asarray(sh, dtype=np.float64)
    degree = sh_degree_from_count(sh.shape[1])
    d = np.asarray(dirs, dtype=np.float64)
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    d = np.divide(d, norm, out=np.zeros_like(d), where=norm > 0)
    basis = sh_basis(d, degree)  # (N, K)
    rgb = np.einsum("nk,nkc->nc", basis, sh) + 0.5
    return np.maximum(rgb, 0.0)
