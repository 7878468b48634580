"""Ground-truth target masks M^v: an image file where any non-zero pixel is target.

Grey-level, RGB and 8- or 16-bit images are accepted (anything OpenCV
decodes losslessly; the protocol uses PNG).  A pixel is target when any of
its colour channels is non-zero; an alpha channel is ignored (a
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
        raw = np.fromfile(path, dtype=np.uint8)
    except OSError as e:
        raise InputError(f"cannot read mask: {e.strerror or e}", path) from None
    _refuse_jpeg(raw[:3].tobytes(), path)
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise InputError("cannot decode mask image (not an image file, or corrupt)", path)
    if img.ndim == 3:
        channels = img.shape[2]
        colour = img[:, :, : channels - 1] if channels in (2, 4) else img
        mask = np.any(colour != 0, axis=2)
        if channels in (2, 4) and not mask.any():
            alpha = img[:, :, channels - 1]
            if alpha.min() != alpha.max():
                from ..util.warning_log import warn

                mask = alpha != 0
                warn("mask has black colour channels and the target in its alpha channel; the alpha channel "
                     "is read as the target (save a grey mask to silence this)", file=path)
    else:
        mask = img != 0
    if shape is not None and mask.shape != tuple(shape):
        h, w = int(shape[0]), int(shape[1])
        mh, mw = mask.shape
        if abs((mw / mh) / (w / h) - 1.0) > _ASPECT_TOLERANCE:
            raise InputError(f"mask is {mw}x{mh}, the view is {w}x{h} (different aspect ratio)", path)
        warnings.warn(f"{path}: mask is {mw}x{mh}, resized to the view's {w}x{h} (nearest neighbour)",
                      R360Warning, stacklevel=2)
        mask = cv2.resize(mask.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    return mask


_JPEG_MAGIC = b"\xff\xd8\xff"


def _refuse_jpeg(head: bytes, path) -> None:
    if head.startswith(_JPEG_MAGIC):
        raise InputError("mask holds JPEG data (whatever its extension): JPEG compression adds non-zero noise "
                         "around the target's edges; save the mask as a real (lossless) PNG", path)


def mask_size(path: str | os.PathLike) -> tuple[int, int]:
    """(H, W) of a mask from its header, with the same refusals as :func:`load_mask` that the
    header decides (JPEG data)."""
    from .renders import image_size

    try:
        with open(path, "rb") as f:
            head = f.read(3)
    except OSError as e:
        raise InputError(f"cannot read mask: {e.strerror or e}", path) from None
    _refuse_jpeg(head, path)
    return image_size(path)
