"""COCO run-length encoding (RLE) of binary masks, without pycocotools.

Format (as written by ``pycocotools.mask.encode`` and read by
``pycocotools.mask.decode``):

* An RLE is a mapping ``{"size": [h, w], "counts": ...}``.
* The mask is flattened in column-major (Fortran) order, i.e. pixel
  ``(row, col)`` is at position ``col * h + row``.
* ``counts`` are the lengths of alternating runs, starting with a run of 0s
  (which is 0 long when the first pixel is set); they sum to ``h * w``.
* *Uncompressed* RLE stores ``counts`` as a list of integers.
* *Compressed* RLE stores ``counts`` as an ASCII string.  Each count ``x``
  (for the count at index ``i >= 3``, the difference ``x - counts[i - 2]``
  instead) is written as a signed little-endian sequence of 5-bit chunks,
  one character per chunk: ``chr(48 + chunk | 0x20 * more)``, where the
  continuation bit ``0x20`` is set on every chunk but the last and bit
  ``0x10`` of the last chunk is the sign.  Characters are therefore in
  ``'0'`` .. ``'o'`` (48..111).  JSON files carry the string as utf-8 text;
  pycocotools itself returns ``bytes``.

Note: the delta coding starts at index 3 (the 4th count), the ``i > 2`` test
in pycocotools' ``rleToString`` / ``rleFrString``.
"""
from __future__ import annotations

import contextvars
import os
from collections.abc import Mapping, Sequence
from contextlib import contextmanager
from numbers import Integral

import numpy as np

from r360gpu.errors import InputError

__all__ = [
    "mask_to_counts",
    "counts_to_mask",
    "counts_to_string",
    "string_to_counts",
    "encode",
    "decode",
]

_PathLike = str | os.PathLike | None

#: Largest decoded mask (pixels) without a view to compare with: the readers' bound.
from r360gpu.io.renders import MAX_PIXELS  # noqa: E402
_limit: contextvars.ContextVar[int | None] = contextvars.ContextVar("r360gpu_rle_limit", default=None)


@contextmanager
def size_limit(max_pixels: int):
    """Within the block, :func:`decode` refuses an RLE whose size claims more than ``max_pixels``
    pixels (the probes set it from the view's size): a 100-byte file can claim 50000 x 50000."""
    token = _limit.set(int(max_pixels))
    try:
        yield
    finally:
        _limit.reset(token)


def max_pixels() -> int:
    """The size bound in force (:func:`size_limit`, else :data:`MAX_PIXELS`)."""
    limit = _limit.get()
    return MAX_PIXELS if limit is None else min(limit, MAX_PIXELS)


def mask_to_counts(mask: np.ndarray) -> np.ndarray:
    """Run lengths of a 2-D mask in column-major order, starting with a 0-run.

    mask: (H, W), any dtype; non-zero = set.  H, W >= 1.
    Returns int64 (M,), summing to H*W; the first entry is 0 when the first
    pixel (row 0, column 0) is set.  An empty mask gives ``[H*W]``, a full
    one ``[0, H*W]`` (the same runs pycocotools produces).
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"mask must be 2-D (H, W), got shape {mask.shape}")
    if mask.size == 0:
        raise ValueError(f"mask must have at least one pixel, got shape {mask.shape}")
    flat = (mask != 0).ravel(order="F")
    change = np.flatnonzero(flat[1:] != flat[:-1]) + 1
    bounds = np.concatenate(([0], change, [flat.size]))
    lengths = np.diff(bounds).astype(np.int64)
    if flat[0]:
        lengths = np.concatenate((np.zeros(1, np.int64), lengths))
    return lengths


def counts_to_mask(counts: Sequence[int] | np.ndarray, height: int, width: int) -> np.ndarray:
    """Rebuild a bool (height, width) mask from run lengths (0-run first).

    The caller guarantees non-negative counts summing to height*width (see
    :func:`decode` for the validating entry point).  Returns a C-contiguous
    bool array.
    """
    counts = np.asarray(counts, dtype=np.int64)
    values = np.zeros(counts.size, dtype=bool)
    values[1::2] = True
    flat = np.repeat(values, counts)
    return np.ascontiguousarray(flat.reshape((height, width), order="F"))


def counts_to_string(counts: Sequence[int] | np.ndarray) -> str:
    """Compress run lengths into the COCO counts string (see module docstring)."""
    counts = [int(c) for c in counts]
    chars: list[str] = []
    for i, count in enumerate(counts):
        x = count - counts[i - 2] if i > 2 else count
        while True:
            chunk = x & 0x1F
            x >>= 5  # arithmetic shift: negative deltas end in a run of -1
            more = (x != -1) if chunk & 0x10 else (x != 0)
            chars.append(chr(48 + (chunk | 0x20 if more else chunk)))
            if not more:
                break
    return "".join(chars)


def string_to_counts(text: str) -> list[int]:
    """Decode a COCO counts string into run lengths.

    Raises ValueError on characters outside '0'..'o' or a string that ends in
    the middle of a number.  The counts are not checked for sign or sum here.
    """
    counts: list[int] = []
    pos, n = 0, len(text)
    while pos < n:
        value, shift = 0, 0
        while True:
            if pos >= n:
                raise ValueError("counts string ends inside a number (last character has the continuation bit)")
            code = ord(text[pos]) - 48
            if not 0 <= code < 64:
                raise ValueError(f"invalid character {text[pos]!r} at position {pos} of the counts string")
            pos += 1
            value |= (code & 0x1F) << shift
            shift += 5
            if not code & 0x20:
                if code & 0x10:
                    value -= 1 << shift  # sign-extend the last chunk
                break
        if len(counts) > 2:
            value += counts[-2]
        counts.append(value)
    return counts


def encode(mask: np.ndarray, *, compressed: bool = True) -> dict:
    """Encode a 2-D mask (non-zero = set) as a COCO RLE dict.

    Returns ``{"size": [H, W], "counts": str}`` (compressed, utf-8 text as in
    JSON dumps) or ``{"size": [H, W], "counts": list[int]}`` (uncompressed).
    """
    mask = np.asarray(mask)
    counts = mask_to_counts(mask)
    h, w = (int(s) for s in mask.shape)
    if compressed:
        return {"size": [h, w], "counts": counts_to_string(counts)}
    return {"size": [h, w], "counts": [int(c) for c in counts]}


def _size(rle: Mapping, path: _PathLike) -> tuple[int, int]:
    size = rle.get("size")
    if (
        not isinstance(size, (list, tuple))
        or len(size) != 2
        or not all(isinstance(s, Integral) and not isinstance(s, bool) for s in size)
    ):
        raise InputError(f"RLE 'size' must be [height, width] integers, got {size!r}", path)
    h, w = int(size[0]), int(size[1])
    if h < 1 or w < 1:
        raise InputError(f"RLE 'size' must be positive, got {[h, w]}", path)
    if h * w > max_pixels():  # checked before the counts are decoded or a pixel allocated
        raise InputError(f"RLE 'size' {h}x{w} is larger than the view allows ({max_pixels()} pixels); "
                         f"not a mask of this view", path)
    return h, w


def decode(rle: Mapping, path: _PathLike = None) -> np.ndarray:
    """Decode a COCO RLE dict (compressed or uncompressed) to a bool (H, W) mask.

    rle: ``{"size": [H, W], "counts": str | bytes | list[int]}``.
    path: the file the RLE came from, named in error messages.
    Raises InputError on a malformed RLE: bad size, bad counts string,
    negative counts, or counts that do not sum to H*W.
    """
    if not isinstance(rle, Mapping):
        raise InputError(f"RLE must be an object with 'size' and 'counts', got {type(rle).__name__}", path)
    if "counts" not in rle or "size" not in rle:
        raise InputError("RLE must have both 'size' and 'counts'", path)
    h, w = _size(rle, path)
    raw = rle["counts"]
    if isinstance(raw, bytes):
        try:
            raw = raw.decode("ascii")
        except UnicodeDecodeError as exc:
            raise InputError(f"RLE counts bytes are not ASCII ({exc})", path) from None
    if isinstance(raw, str):
        try:
            counts = string_to_counts(raw)
        except ValueError as exc:
            raise InputError(f"bad RLE counts string: {exc}", path) from None
    elif isinstance(raw, (list, tuple)):
        if not all(isinstance(c, Integral) and not isinstance(c, bool) for c in raw):
            raise InputError("uncompressed RLE counts must be a list of integers", path)
        counts = [int(c) for c in raw]
    else:
        raise InputError(f"RLE counts must be a string or a list of integers, got {type(raw).__name__}", path)
    if any(c < 0 for c in counts):
        raise InputError("RLE has a negative run length", path)
    total = sum(counts)
    if total != h * w:
        raise InputError(f"RLE counts sum to {total}, but size {h}x{w} needs {h * w}", path)
    return counts_to_mask(counts, h, w)
