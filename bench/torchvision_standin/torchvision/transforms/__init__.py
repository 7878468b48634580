from enum import Enum
from typing import List

import torch
import torch.nn.functional as _F
from torch import nn

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


class ToTensor:
    """transforms.ToTensor for what SAM2 passes (an HWC uint8 or float ndarray):
    CHW, uint8 -> float32 divided by 255 (torchvision's F.to_tensor)."""

    def __call__(self, pic):
        import numpy as np

        if not isinstance(pic, np.ndarray) or pic.ndim != 3:
            raise TypeError("the stand-in ToTensor takes an (H, W, C) numpy array (what SAM2 passes)")
        img = torch.from_numpy(pic.transpose((2, 0, 1))).contiguous()
        if img.dtype == torch.uint8:
            return img.to(dtype=torch.get_default_dtype()).div(255)
        return img


class Resize(nn.Module):
    """transforms.Resize((h, w)) on a float tensor: torchvision's tensor path is
    F.interpolate(bilinear, align_corners=False, antialias=True) on a batch of one."""

    def __init__(self, size: List[int]):
        super().__init__()
        if isinstance(size, int) or len(size) != 2:
            raise TypeError("the stand-in Resize takes an (h, w) size (what SAM2 passes)")
        self.size = [int(size[0]), int(size[1])]

    def forward(self, img: torch.Tensor) -> torch.Tensor:
        if not img.is_floating_point():
            raise TypeError("the stand-in Resize takes float tensors (what SAM2 passes)")
        squeeze = img.dim() == 3
        x = img.unsqueeze(0) if squeeze else img
        x = _F.interpolate(x, size=self.size, mode="bilinear", align_corners=False, antialias=True)
        return x.squeeze(0) if squeeze else x


class Normalize(nn.Module):
    """transforms.Normalize: (x - mean) / std with float32 mean / std (F_t.normalize)."""

    def __init__(self, mean: List[float], std: List[float]):
        super().__init__()
        self.mean = [float(v) for v in mean]
        self.std = [float(v) for v in std]

    def forward(self, tensor: torch.Tensor) -> torch.Tensor:
        mean = torch.tensor(self.mean, dtype=tensor.dtype).view(-1, 1, 1)
        std = torch.tensor(self.std, dtype=tensor.dtype).view(-1, 1, 1)
        return tensor.clone().sub_(mean).div_(std)
