"""Folders of precomputed masks: the check every source folder passes, and the simplest format.

``png`` -- one mask image per view, ``<name>.png``, any non-zero pixel is the mask (colour images:
any non-zero colour channel; alpha is ignored).  This is the public Remove360 evaluation layout
``gsam2/{before,after}/mask/``, which the public ``remove360/evaluation/semantic.py`` reads with
``cv2.imread(..., IMREAD_GRAYSCALE)`` and binarises with ``> 0``.  PNG masks are already per prompt:
the prompt becomes their label.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError
from r360gpu.probes.base import SemanticPrediction
from r360gpu.util.filehash import input_stamp


def mask_dir(directory: str | os.PathLike) -> Path:
    """``directory`` as a Path, or an InputError when it is not a folder."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("mask directory does not exist", directory)
    return directory


def read_mask_png(path: str | os.PathLike) -> np.ndarray:
    """bool (H, W) from a mask image: non-zero = mask (colour: any colour channel;
    alpha ignored).  The same reader as the target masks (:func:`r360gpu.io.load_mask`)."""
    from ..io.masks import load_mask

    return load_mask(path)


class PngMaskDir:
    """Directory of per-view mask images ``<name>.png`` (non-zero = mask)."""

    format = "png"

    def __init__(self, directory: str | os.PathLike):
        self.directory = mask_dir(directory)

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.directory.glob("*.png"))

    def path_for(self, name: str) -> Path:
        return self.directory / f"{name}.png"

    def stamps(self, name: str) -> dict:
        """{path: :func:`~r360gpu.util.filehash.input_stamp`} of what :meth:`read` reads for ``name``."""
        path = self.path_for(name)
        return {str(path): input_stamp(path)}

    def read(self, name: str, prompt: str, probe: str = "") -> SemanticPrediction | None:
        """K = 1 instance labelled ``prompt`` (score NaN: the file carries none),
        K = 0 for an all-zero mask, None when the file is missing."""
        path = self.path_for(name)
        if not path.is_file():
            return None
        mask = read_mask_png(path)
        if not mask.any():
            return SemanticPrediction(np.zeros((0, *mask.shape), bool), np.zeros(0, np.float32), [], probe)
        return SemanticPrediction(mask[None], np.full(1, np.nan, np.float32), [prompt], probe)

