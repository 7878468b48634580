from enum import Enum

from . import functional  # noqa: F401


class InterpolationMode(Enum):
    """Names only (transformers imports the enum; the parity scripts never resize through it)."""

    NEAREST = "nearest"
    NEAREST_EXACT = "nearest-exact"
    BILINEAR = "bilinear"
    BICUBIC = "bicubic"
    BOX = "box"
    HAMMING = "hamming"
    LANCZOS = "lanczos"
