"""PlayCanvas / SuperSplat ``.compressed.ply``: reader and writer.

Layout (binary PLY, as written by SuperSplat and ``splat-transform``):

* ``chunk`` element, one record per 256 consecutive Gaussians (the last
  chunk may be partial; ``chunk count == ceil(N / 256)``), float properties
  ``min_x min_y min_z max_x max_y max_z`` (position bounds),
  ``min_scale_x .. max_scale_z`` (bounds of the LOG scales) and optionally
  ``min_r min_g min_b max_r max_g max_b`` (bounds of the colour
  ``0.5 + C0 * f_dc``; without them the 8-bit colour is the colour itself).
* ``vertex`` element, four uint32 per Gaussian (bit 31 is the MSB):

  - ``packed_position``: x in bits 21-31 (11 bits), y in 11-20 (10 bits),
    z in 0-10 (11 bits); each an unsigned normalised fraction ``t`` of the
    chunk range: ``value = min + t * (max - min)``.
  - ``packed_scale``: same 11/10/11 layout over the chunk's log-scale range;
    the linear scale is ``exp(value)``.
  - ``packed_rotation``: "smallest three": bits 30-31 hold the index i (0..3)
    of the largest-magnitude component of the (w, x, y, z) quaternion (made
    positive by flipping the sign of q); the three other components, in
    increasing index order, are 10-bit fractions in bits 20-29, 10-19, 0-9,
    each encoding ``v * sqrt(2)/2 + 0.5`` (|v| <= 1/sqrt(2)); the largest
    component is ``sqrt(1 - sum of squares of the others)``.
  - ``packed_color``: R in bits 24-31, G 16-23, B 8-15, A 0-7, each 8-bit
    fraction; RGB over the chunk colour range, ``f_dc = (colour - 0.5) / C0``;
    A is the opacity (after the sigmoid).

* optional ``sh`` element, one record per Gaussian: uchar ``f_rest_0..M-1``
  (M in 9, 24, 45; channel-major as in the INRIA layout).  A byte q decodes
  to ``f = q * 8 / 255 - 4``, the format's reference decoder (PlayCanvas
  engine, ``src/scene/gsplat/gsplat-compressed-data.js``:
  ``shData[j][i * 16 + k] * (8 / 255) - 4``, and the same in its shader chunk
  ``compressedSH.js``); the writer stores the nearest byte,
  ``q = round((f + 4) * 255 / 8)`` clipped to 0..255.

Round-trip error bounds of :func:`save_compressed_ply` then
:func:`load_compressed_ply` (with ``r`` the range of the quantity over the
Gaussian's chunk; these are what the tests check):

* mean, per axis:         r / (2 * 2047) for x and z, r / (2 * 1023) for y
* log-scale, per axis:    same as the mean, with r the chunk's log-scale range
* f_dc, per channel:      r_colour / (2 * 255 * C0)
* opacity:                1 / (2 * 255)
* quaternion (up to sign, as a 4-vector): 4 * sqrt(3) * delta with
  delta = sqrt(2) / (2 * 1023) the error of a stored component (the largest
  component is recomputed from the other three, |d m| <= 3 delta, and the
  result is renormalised): about 4.8e-3
* f_rest:                 4/255 (half a step of 8/255) for values in [-4, 4];
  values outside [-4, 4] are clipped.
"""
from __future__ import annotations

import os
import warnings

import numpy as np
from numpy.lib.recfunctions import structured_to_unstructured

from ..errors import InputError, R360Warning
from .gaussians import Gaussians, build_gaussians
from .ply import PlyData, read_ply, write_ply
from .sh import C0

CHUNK_SIZE = 256
_CHUNK_BOUNDS = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                 "min_scale_x", "min_scale_y", "min_scale_z",
                 "max_scale_x", "max_scale_y", "max_scale_z"]
_CHUNK_COLOUR = ["min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
_PACKED = ["packed_position", "packed_rotation", "packed_scale", "packed_color"]
_VALID_REST_COUNTS = {9: 1, 24: 2, 45: 3}
_SQRT2 = float(np.sqrt(2.0))
# f_rest value of each byte 0..255: the PlayCanvas engine's decoder (see the module docstring).
_SH_BYTE_VALUES = np.arange(256, dtype=np.float64) * (8.0 / 255.0) - 4.0


def is_compressed_ply(ply: PlyData) -> bool:
    """True if the header has a ``chunk`` element and a ``vertex`` element with ``packed_position``."""
    v = ply.element("vertex")
    return ply.element("chunk") is not None and v is not None and "packed_position" in v.property_names()


def load_compressed_ply(path: str | os.PathLike) -> Gaussians:
    """Read a PlayCanvas/SuperSplat .compressed.ply; see the module docstring."""
    return gaussians_from_compressed_ply(read_ply(path))


def _unorm(word: np.ndarray, shift: int, bits: int) -> np.ndarray:
    mask = (1 << bits) - 1
    return ((word >> np.uint32(shift)) & np.uint32(mask)).astype(np.float64) / mask


def _lerp(lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> np.ndarray:
    return lo * (1.0 - t) + hi * t


def check_compressed_header(ply: PlyData) -> None:
    """Every check of a compressed PLY that its header decides (InputError naming the file);
    :func:`gaussians_from_compressed_ply` and ``r360gpu check`` both run it."""
    path = ply.path
    chunk_el, vert_el, sh_el = ply.element("chunk"), ply.element("vertex"), ply.element("sh")
    if chunk_el is None or vert_el is None:
        raise InputError("compressed PLY needs 'chunk' and 'vertex' elements", path)
    chunk_names, vert_names = chunk_el.property_names(), vert_el.property_names()
    missing = [p for p in _CHUNK_BOUNDS if p not in chunk_names] + \
              [p for p in _PACKED if p not in vert_names]
    if missing:
        raise InputError(f"compressed PLY is missing properties: {', '.join(missing)}", path)
    has_colour = [p in chunk_names for p in _CHUNK_COLOUR]
    if any(has_colour) and not all(has_colour):
        raise InputError("compressed PLY chunk element has only some of min_r..max_b", path)
    for p in vert_el.properties:
        if p.name in _PACKED and p.code not in ("u4", "i4"):
            raise InputError(f"{p.name} must be a 32-bit integer property", path)
    n = vert_el.count
    n_chunks = -(-n // CHUNK_SIZE)
    if chunk_el.count != n_chunks:
        raise InputError(
            f"wrong element counts: {n} vertices need {n_chunks} chunks of {CHUNK_SIZE}, "
            f"the header declares {chunk_el.count}", path)
    rest_names: list[str] = []
    if sh_el is not None:
        rest_names = sh_el.property_names()
        if len(rest_names) not in _VALID_REST_COUNTS or \
                rest_names != [f"f_rest_{i}" for i in range(len(rest_names))]:
            raise InputError("sh element must hold f_rest_0..f_rest_M-1 with M = 9, 24 or 45", path)
        if any(p.code != "u1" for p in sh_el.properties):
            raise InputError("sh element properties must be uchar", path)
        if sh_el.count != n:
            raise InputError(f"wrong element counts: {n} vertices but {sh_el.count} sh records", path)
    if n == 0:
        raise InputError("contains no Gaussians", path)


def gaussians_from_compressed_ply(ply: PlyData) -> Gaussians:
    """Decode an already parsed compressed PLY (drop policy of :func:`build_gaussians`)."""
    check_compressed_header(ply)
    path = ply.path
    chunk_el, vert_el, sh_el = ply.element("chunk"), ply.element("vertex"), ply.element("sh")
    chunk_names, vert_names = chunk_el.property_names(), vert_el.property_names()
    n = vert_el.count
    rest_names = sh_el.property_names() if sh_el is not None else []
    has_colour = [p in chunk_names for p in _CHUNK_COLOUR]
    known_el = {"chunk", "vertex", "sh"}
    extra = [e.name for e in ply.elements if e.name not in known_el] + \
            [f"vertex.{p}" for p in vert_names if p not in _PACKED] + \
            [f"chunk.{p}" for p in chunk_names if p not in _CHUNK_BOUNDS + _CHUNK_COLOUR]
    if extra:
        warnings.warn(f"{path}: ignoring {', '.join(extra)} (not part of the compressed layout)",
                      R360Warning, stacklevel=3)

    ch = ply.arrays["chunk"]
    v = ply.arrays["vertex"]
    ci = np.arange(n) // CHUNK_SIZE

    def bound(name: str) -> np.ndarray:
        return ch[name].astype(np.float64)[ci]

    pp, pr, ps, pc = (v[k].astype(np.uint32) for k in _PACKED)
    fields = ((21, 11), (11, 10), (0, 11))
    means = np.stack([_lerp(bound(f"min_{a}"), bound(f"max_{a}"), _unorm(pp, s, b))
                      for a, (s, b) in zip("xyz", fields)], axis=1)
    with np.errstate(over="ignore", invalid="ignore"):
        scales = np.exp(np.stack([_lerp(bound(f"min_scale_{a}"), bound(f"max_scale_{a}"), _unorm(ps, s, b))
                                  for a, (s, b) in zip("xyz", fields)], axis=1))
    rgb = np.stack([_unorm(pc, s, 8) for s in (24, 16, 8)], axis=1)
    if has_colour[0]:
        rgb = np.stack([_lerp(bound(f"min_{c}"), bound(f"max_{c}"), rgb[:, i])
                        for i, c in enumerate("rgb")], axis=1)
    opacities = _unorm(pc, 0, 8)

    small = np.stack([(_unorm(pr, s, 10) - 0.5) * _SQRT2 for s in (20, 10, 0)], axis=1)
    largest = np.sqrt(np.maximum(0.0, 1.0 - np.sum(small ** 2, axis=1)))
    which = (pr >> np.uint32(30)).astype(np.int64)
    quats = np.empty((n, 4), np.float64)
    for i in range(4):
        sel = which == i
        others = [j for j in range(4) if j != i]
        quats[sel, i] = largest[sel]
        quats[np.ix_(sel, others)] = small[sel]

    k = 1 + len(rest_names) // 3
    sh = np.zeros((n, k, 3), np.float64)
    sh[:, 0, :] = (rgb - 0.5) / C0
    if rest_names:
        q = structured_to_unstructured(ply.arrays["sh"][rest_names])  # (n, M) uint8
        sh[:, 1:, :] = _SH_BYTE_VALUES[q].reshape(n, 3, k - 1).transpose(0, 2, 1)
    return build_gaussians(means, scales, quats, opacities, sh, source=path)


def _pack_unorm(t: np.ndarray, bits: int) -> np.ndarray:
    mask = (1 << bits) - 1
    return np.clip(np.floor(t * mask + 0.5), 0, mask).astype(np.uint32)


def _chunk_fraction(values: np.ndarray, n_chunks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-chunk (min, max) of ``values`` (C*256, D) and each value's fraction of its chunk range."""
    per_chunk = values.reshape(n_chunks, CHUNK_SIZE, -1)
    # The bounds are stored as float32: quantise relative to the stored values.
    lo = per_chunk.min(axis=1).astype(np.float32).astype(np.float64)
    hi = per_chunk.max(axis=1).astype(np.float32).astype(np.float64)
    span = hi - lo
    safe = np.where(span > 0, span, 1.0)
    t = np.where(span[:, None, :] > 0, (per_chunk - lo[:, None, :]) / safe[:, None, :], 0.0)
    return lo, hi, np.clip(t, 0.0, 1.0).reshape(values.shape)


def save_compressed_ply(path: str | os.PathLike, gaussians: Gaussians) -> None:
    """Write ``gaussians`` as a .compressed.ply (atomically), keeping their order.

    Unlike SuperSplat this writer does not reorder Gaussians (e.g. along a
    Morton curve), so loading gives them back in the same order; chunk ranges
    are then wider and quantisation coarser, within the bounds in the module
    docstring.  The 18-property chunk layout (with colour bounds) is written,
    and an ``sh`` element when the SH degree is above 0.
    """
    g = gaussians
    n = g.n
    if n == 0:
        raise ValueError("cannot write an empty scene")
    n_chunks = -(-n // CHUNK_SIZE)
    # Pad the last chunk by repeating the last Gaussian: chunk min/max are unchanged.
    pad = np.concatenate([np.arange(n), np.full(n_chunks * CHUNK_SIZE - n, n - 1)])

    def padded(a: np.ndarray) -> np.ndarray:
        return a.astype(np.float64)[pad]

    pos_lo, pos_hi, pos_t = _chunk_fraction(padded(g.means), n_chunks)
    sc_lo, sc_hi, sc_t = _chunk_fraction(np.log(padded(g.scales)), n_chunks)
    col_lo, col_hi, col_t = _chunk_fraction(0.5 + C0 * padded(g.sh[:, 0, :]), n_chunks)

    def pack_111011(t: np.ndarray) -> np.ndarray:
        return (_pack_unorm(t[:, 0], 11) << np.uint32(21)) | (_pack_unorm(t[:, 1], 10) << np.uint32(11)) \
            | _pack_unorm(t[:, 2], 11)

    alpha = _pack_unorm(padded(g.opacities), 8)
    colour = (_pack_unorm(col_t[:, 0], 8) << np.uint32(24)) | (_pack_unorm(col_t[:, 1], 8) << np.uint32(16)) \
        | (_pack_unorm(col_t[:, 2], 8) << np.uint32(8)) | alpha

    q = padded(g.quats)
    which = np.argmax(np.abs(q), axis=1)
    q *= np.where(q[np.arange(len(q)), which] < 0, -1.0, 1.0)[:, None]
    rot = which.astype(np.uint32)
    for slot in range(3):
        # The slot-th component that is not the largest one, in increasing index order.
        idx = slot + (which <= slot).astype(np.int64)
        comp = q[np.arange(len(q)), idx]
        rot = (rot << np.uint32(10)) | _pack_unorm(comp * (_SQRT2 * 0.5) + 0.5, 10)

    chunk = np.zeros(n_chunks, dtype=[(p, "<f4") for p in _CHUNK_BOUNDS + _CHUNK_COLOUR])
    for i, a in enumerate("xyz"):
        chunk[f"min_{a}"], chunk[f"max_{a}"] = pos_lo[:, i], pos_hi[:, i]
        chunk[f"min_scale_{a}"], chunk[f"max_scale_{a}"] = sc_lo[:, i], sc_hi[:, i]
    for i, c in enumerate("rgb"):
        chunk[f"min_{c}"], chunk[f"max_{c}"] = col_lo[:, i], col_hi[:, i]
    vert = np.zeros(n, dtype=[(p, "<u4") for p in _PACKED])
    vert["packed_position"] = pack_111011(pos_t)[:n]
    vert["packed_rotation"] = rot[:n]
    vert["packed_scale"] = pack_111011(sc_t)[:n]
    vert["packed_color"] = colour[:n]
    elements = [("chunk", chunk), ("vertex", vert)]
    k = g.sh.shape[1]
    if k > 1:
        rest = g.sh[:, 1:, :].astype(np.float64).transpose(0, 2, 1).reshape(n, -1)
        q8 = np.clip(np.rint((rest + 4.0) * (255.0 / 8.0)), 0, 255).astype(np.uint8)
        sh = np.zeros(n, dtype=[(f"f_rest_{i}", "u1") for i in range(q8.shape[1])])
        for i in range(q8.shape[1]):
            sh[f"f_rest_{i}"] = q8[:, i]
        elements.append(("sh", sh))
    write_ply(path, elements, comments=["written by r360gpu"])
