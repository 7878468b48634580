"""torchvision.transforms.functional for PIL inputs (what segment-anything and GroundingDINO pass)."""
import numpy as np
from PIL import Image


def to_pil_image(pic, mode=None):
    return Image.fromarray(np.asarray(pic), mode=mode)


def resize(img, size, interpolation=None, max_size=None, antialias=True):
    if not isinstance(img, Image.Image):
        raise TypeError("the stand-in resize takes PIL images (what Grounded-SAM-2 passes)")
    if isinstance(size, int):
        raise TypeError("the stand-in resize takes an (h, w) size")
    h, w = size
    return img.resize((int(w), int(h)), Image.BILINEAR)
