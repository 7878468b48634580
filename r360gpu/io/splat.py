"""The headerless ``.splat`` format (antimatter15 web viewer): reader and writer.

The file is N records of 32 bytes, little-endian, no header:

* bytes  0-11  position, 3 x float32 (world)
* bytes 12-23  scale, 3 x float32, LINEAR (not log)
* bytes 24-27  colour RGBA, 4 x uint8: RGB = (0.5 + C0 * f_dc) * 255,
  A = opacity * 255 (opacity after the sigmoid)
* bytes 28-31  rotation, 4 x uint8 in (w, x, y, z) order: q * 128 + 128
  (clipped to 0..255); decoded as (byte - 128) / 128 and renormalised.

Only SH degree 0 is stored.

Round-trip error bounds of :func:`save_splat` then :func:`load_splat` (the
writer rounds to nearest):

* mean, scale:  exact (float32)
* f_dc:         1 / (2 * 255 * C0) ~ 6.95e-3 for f_dc in [-0.5/C0, 0.5/C0]
  (colour in [0, 1]); colours outside are clipped
* opacity:      1 / (2 * 255)
* quaternion (same sign, as a 4-vector): a stored component is off by at
  most 1/256 (1/128 for a component equal to 1, since 256 clips to 255), so
  the raw vector is off by at most sqrt(7)/256 and the renormalised one by at
  most twice that, sqrt(7)/128 ~ 0.0207.
"""
from __future__ import annotations

import os
import warnings

import numpy as np

from ..errors import InputError, R360Warning
from ..util.filehash import read_file
from .paths import read_error
from ..util.atomic import write_bytes
from .gaussians import Gaussians, build_gaussians
from .sh import C0

RECORD_DTYPE = np.dtype([
    ("position", "<f4", (3,)),
    ("scale", "<f4", (3,)),
    ("rgba", "u1", (4,)),
    ("rot", "u1", (4,)),
])
assert RECORD_DTYPE.itemsize == 32


def load_splat(path: str | os.PathLike) -> Gaussians:
    """Read a .splat file; see the module docstring (drop policy of :func:`build_gaussians`)."""
    path = os.fspath(path)
    try:
        data = read_file(path)  # hashed as read (util.filehash): the cache key is what was decoded
    except OSError as e:
        raise read_error(e, path) from None
    if len(data) == 0:
        raise InputError("empty .splat file (contains no Gaussians)", path)
    if len(data) % RECORD_DTYPE.itemsize:
        raise InputError(
            f"truncated .splat file: {len(data)} bytes is not a multiple of the "
            f"{RECORD_DTYPE.itemsize}-byte record", path)
    rec = np.frombuffer(data, dtype=RECORD_DTYPE)
    rgba = rec["rgba"].astype(np.float64) / 255.0
    sh = ((rgba[:, :3] - 0.5) / C0)[:, None, :]
    quats = (rec["rot"].astype(np.float64) - 128.0) / 128.0
    return build_gaussians(rec["position"], rec["scale"], quats, rgba[:, 3], sh, source=path)


def save_splat(path: str | os.PathLike, gaussians: Gaussians) -> None:
    """Write ``gaussians`` as a .splat file (atomically), in their order.

    SH bands above degree 0 cannot be stored; if present they are discarded
    with an R360Warning.
    """
    g = gaussians
    if g.sh_degree > 0:
        warnings.warn(f"{os.fspath(path)}: .splat stores SH degree 0 only; "
                      f"discarding degree 1..{g.sh_degree} coefficients", R360Warning, stacklevel=2)
    rec = np.zeros(g.n, dtype=RECORD_DTYPE)
    rec["position"] = g.means
    rec["scale"] = g.scales
    colour = 0.5 + C0 * g.sh[:, 0, :].astype(np.float64)
    rec["rgba"][:, :3] = np.clip(np.round(colour * 255.0), 0, 255)
    rec["rgba"][:, 3] = np.clip(np.round(g.opacities.astype(np.float64) * 255.0), 0, 255)
    rec["rot"] = np.clip(np.round(g.quats.astype(np.float64) * 128.0 + 128.0), 0, 255)
    write_bytes(path, rec.tobytes())
