"""Ground-truth target masks M^v: an image file where any non-zero pixel is target.

Grey-level, RGB and 8- or 16-bit images are accepted (anything OpenCV
decodes losslessly; the protocol uses PNG).  A pixel is target when any of
its colour channels is non-zero, except in a palette (indexed-colour) PNG,
which is a label map: index 0 is background and every other index is target,
whatever colour the palette gives it (the DAVIS / PASCAL VOC convention),
with a warning when the colours say otherwise (index 0 not black, or another
index black); an alpha channel is ignored (a
transparent-background PNG would otherwise be all target), except when every
colour channel is 0 and the alpha channel varies: then the target can only
be in the alpha channel (a cut-out exported as black with the object opaque),
which is read as the target, with a warning.

JPEG data are refused, whatever the file's extension (JPEG bytes saved as
``.png`` happen): lossy compression puts non-zero noise around every edge,
which would silently grow the target by a few percent.
"""
from __future__ import annotations

import os
import warnings

import cv2
import numpy as np

from ..errors import InputError, R360Warning
from ..util.filehash import read_file
from .paths import read_error

# Masks whose aspect ratio differs from the requested one by more than this
# (relative) are not resized but rejected: they do not belong to that view.
_ASPECT_TOLERANCE = 0.01


def load_mask(path: str | os.PathLike, shape: tuple[int, int] | None = None) -> np.ndarray:
    """Read a target mask as a bool array (H, W), True = target.

    shape: optional (H, W) the mask must have (the rendered view's size).  A
    mask of another size with the same aspect ratio (within 1%) is resized
    with nearest-neighbour sampling and an R360Warning; a different aspect
    ratio is an InputError.  Unreadable or undecodable files are an InputError.
    """
    path = os.fspath(path)
    try:
        raw = np.frombuffer(read_file(path), dtype=np.uint8)  # hashed as read (util.filehash)
    except OSError as e:
        raise read_error(e, path, "mask") from None
    _refuse_jpeg(raw[:3].tobytes(), path)
    from .renders import check_pixel_count, check_png_chunks

    check_pixel_count(raw[:1 << 16].tobytes(), path, "mask")
    check_png_chunks(raw, path, "mask")
    if _is_palette_png(raw[:32].tobytes()):
        mask = _palette_mask(raw, path)
    else:
        mask = _colour_mask(raw, path)
    if shape is not None and mask.shape != tuple(shape):
        h, w = int(shape[0]), int(shape[1])
        mh, mw = mask.shape
        if abs((mw / mh) / (w / h) - 1.0) > _ASPECT_TOLERANCE:
            raise InputError(f"mask is {mw}x{mh}, the view is {w}x{h} (different aspect ratio)", path)
        warnings.warn(f"{path}: mask is {mw}x{mh}, resized to the view's {w}x{h} (nearest neighbour)",
                      R360Warning, stacklevel=2)
        mask = cv2.resize(mask.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    return mask


def _colour_mask(raw: np.ndarray, path) -> np.ndarray:
    """Grey, RGB(A) masks: any non-zero colour channel is target (alpha: see the module docstring)."""
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise InputError("cannot decode mask image (not an image file, or corrupt)", path)
    if img.ndim != 3:
        return img != 0
    channels = img.shape[2]
    n_colour = channels - 1 if channels in (2, 4) else channels
    if img.dtype.kind in "ui":
        # OR of the colour planes: whole-plane passes, where np.any(..., axis=2) reduces 3-4 values per pixel
        colour = img[:, :, 0].copy()
        for c in range(1, n_colour):
            np.bitwise_or(colour, img[:, :, c], out=colour)
        mask = colour != 0
    else:  # float images (TIFF): NaN and -0.0 must read as they compare
        mask = np.any(img[:, :, :n_colour] != 0, axis=2)
    if channels in (2, 4) and not mask.any():
        alpha = img[:, :, channels - 1]
        if alpha.min() != alpha.max():
            from ..util.warning_log import warn

            mask = alpha != 0
            warn("mask has black colour channels and the target in its alpha channel; the alpha channel "
                 "is read as the target (save a grey mask to silence this)", file=path)
    return mask


def _is_palette_png(head: bytes) -> bool:
    """True for a PNG whose IHDR colour type is 3 (indexed colour)."""
    return head.startswith(b"\x89PNG\r\n\x1a\n") and len(head) > 25 and head[12:16] == b"IHDR" and head[25] == 3


def _palette_mask(raw: np.ndarray, path) -> np.ndarray:
    """A palette PNG is a label map: index 0 is background, every other index is target, whatever
    colours the palette gives them (the DAVIS / PASCAL VOC convention; the colours are for display).
    Where that differs from the colour rule (index 0 not black, or another index black), the
    reading is warned and recorded."""
    import io

    from PIL import Image

    try:
        with Image.open(io.BytesIO(raw.tobytes())) as im:
            if im.mode != "P":  # e.g. a 1-bit palette PIL opens as "1": decoded by colour
                return _colour_mask(raw, path)
            index = np.asarray(im)
            palette = np.asarray(im.getpalette() or [0, 0, 0], np.uint8).reshape(-1, 3)
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
        raise InputError(f"cannot decode palette mask ({e})", path) from None
    mask = index != 0
    used = np.unique(index)
    black = ~palette.any(axis=1)
    colour_rule_differs = any(
        (int(i) < len(palette) and bool(black[i])) == (i != 0) for i in used)
    if colour_rule_differs:
        from ..util.warning_log import warn

        warn(f"palette mask whose colours disagree with its indices (index 0 is "
             f"{'black' if black[0] else 'RGB ' + str(tuple(int(c) for c in palette[0]))}): read as a label map, "
             f"index 0 = background, any other index = target", file=path)
    return mask


def _refuse_jpeg(head: bytes, path) -> None:
    from .renders import refuse_lossy

    refuse_lossy(head, path, "mask")


def mask_size(path: str | os.PathLike) -> tuple[int, int]:
    """(H, W) of a mask from its header, with the same refusals as :func:`load_mask` that the
    header decides (JPEG data)."""
    from .renders import image_size

    try:
        with open(path, "rb") as f:
            head = f.read(3)
    except OSError as e:
        raise read_error(e, path, "mask") from None
    _refuse_jpeg(head, path)
    return image_size(path)
