"""SAM automatic-mask records as JSON (format ``sam-json``): ``<name>.json`` per view, or ``merged.json``.

A file holds a list of ``{"segmentation", "area", "bbox", ...}`` where ``segmentation`` is a nested
row-major H x W list of 0/1 (or true/false) or a COCO RLE; the key ``"mask"`` is accepted in place
of ``"segmentation"``; ``predicted_iou``, when every record has it, becomes the scores.  ``area`` and
``bbox`` are not used.  A ``merged.json`` mapping image name -> record list, when present, is used
instead of the per-view files (image names lose a .png/.jpg/.jpeg extension).  This is the public
layout ``sam/after/``: ``scripts/run_sam_on_rgb.py`` writes ``{"segmentation": bool_mask.tolist(),
"area", "bbox"}`` records; ``remove360/utils/io.py:load_sam_data`` reads ``merged.json`` if present,
else every ``*.json`` keyed by stem; ``remove360/evaluation/sam.py`` takes ``"mask"`` or
``"segmentation"``.  The nested lists are read fast by :mod:`r360gpu.probes.sam_json`.
"""
from __future__ import annotations

import os
from numbers import Real
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError
from r360gpu.probes import rle, sam_json
from r360gpu.probes.base import MaskSet
from r360gpu.probes.mask_dirs import mask_dir
from r360gpu.util.filehash import input_stamp

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _segmentation_mask(seg, where: str, path: Path) -> np.ndarray:
    """bool (H, W) from a nested 0/1 list, such a list already decoded by
    :func:`r360gpu.probes.sam_json.load`, or a COCO RLE object."""
    if isinstance(seg, np.ndarray):
        return seg
    if isinstance(seg, dict):
        try:
            return rle.decode(seg, path)
        except InputError as exc:
            raise InputError(f"{where}: {exc.problem}", path) from None
    if not isinstance(seg, list):
        raise InputError(f"{where}: 'segmentation' must be a nested list or a COCO RLE, got {type(seg).__name__}", path)
    try:
        arr = np.array(seg)
    except ValueError:
        raise InputError(f"{where}: 'segmentation' rows have different lengths", path) from None
    if arr.ndim != 2 or arr.size == 0:
        raise InputError(f"{where}: 'segmentation' must be a non-empty H x W nested list, got shape {arr.shape}", path)
    if arr.dtype == bool:
        return arr
    if arr.dtype.kind not in "iuf" or not np.isin(arr, (0, 1)).all():
        raise InputError(f"{where}: 'segmentation' values must be 0/1 or true/false", path)
    return arr != 0


def read_sam_records(records, path: str | os.PathLike, probe: str = "") -> MaskSet:
    """A MaskSet from a list of SAM automatic-mask records (see module docstring).

    path names the file the records came from (for errors).  All masks must
    share one size; an empty list gives K = 0 at size 0 x 0.
    """
    path = Path(path)
    if not isinstance(records, list):
        raise InputError(f"SAM masks must be a list of records, got {type(records).__name__}", path)
    masks, scores = [], []
    for i, rec in enumerate(records):
        where = f"record {i}"
        if not isinstance(rec, dict):
            raise InputError(f"{where} is not an object", path)
        seg = rec.get("segmentation", rec.get("mask"))
        if seg is None:
            raise InputError(f"{where} has no 'segmentation'", path)
        mask = _segmentation_mask(seg, where, path)
        if masks and mask.shape != masks[0].shape:
            raise InputError(
                f"{where}: segmentation is {mask.shape[0]}x{mask.shape[1]}, record 0 is "
                f"{masks[0].shape[0]}x{masks[0].shape[1]}",
                path,
            )
        masks.append(mask)
        iou = rec.get("predicted_iou")
        scores.append(float(iou) if isinstance(iou, Real) and not isinstance(iou, bool) else None)
    if not masks:
        return MaskSet(np.zeros((0, 0, 0), bool), None, probe)
    have_scores = all(s is not None for s in scores)
    return MaskSet(np.stack(masks), np.asarray(scores, np.float32) if have_scores else None, probe)


def read_sam_json(path: str | os.PathLike, probe: str = "") -> MaskSet:
    """A MaskSet from one per-image SAM JSON file (a list of records)."""
    path = Path(path)
    return read_sam_records(sam_json.load(path), path, probe)


def _strip_image_suffix(name: str) -> str:
    lower = name.lower()
    for suffix in _IMAGE_SUFFIXES:
        if lower.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return name


class SamJsonDir:
    """Directory of SAM automatic-mask JSON: ``merged.json`` if present, else ``<name>.json``."""

    format = "sam-json"

    def __init__(self, directory: str | os.PathLike):
        self.directory = mask_dir(directory)
        self._merged_path = self.directory / "merged.json"
        self._merged: dict[str, list] | None = None
        self._merged_stamp = None
        # taken where merged.json or the per-view files are chosen: a merged.json added later changes that
        self._dir_stamp = input_stamp(self.directory)
        if self._merged_path.is_file():
            self._merged_stamp = input_stamp(self._merged_path)  # before reading it
            data = sam_json.load(self._merged_path)
            if not isinstance(data, dict):
                raise InputError("merged SAM masks must map image names to record lists", self._merged_path)
            self._merged = {}
            for key, records in data.items():
                name = _strip_image_suffix(key)
                if name in self._merged:
                    raise InputError(f"two entries for view {name!r}", self._merged_path)
                self._merged[name] = records

    def names(self) -> list[str]:
        if self._merged is not None:
            return sorted(self._merged)
        return sorted(p.stem for p in self.directory.glob("*.json"))

    def path_for(self, name: str) -> Path:
        return self._merged_path if self._merged is not None else self.directory / f"{name}.json"

    def stamps(self, name: str) -> dict:
        """{path: :func:`~r360gpu.util.filehash.input_stamp`} of what :meth:`read` reads for ``name``, and
        of the folder (``merged.json`` and the folder: as they were when this reader looked at them)."""
        if self._merged is not None:
            return {str(self.directory): self._dir_stamp, str(self._merged_path): self._merged_stamp}
        path = self.path_for(name)
        return {str(self.directory): self._dir_stamp, str(path): input_stamp(path)}

    def read(self, name: str, probe: str = "") -> MaskSet | None:
        """The view's masks at the file's size, or None when there is no entry."""
        if self._merged is not None:
            records = self._merged.get(name)
            if records is None:
                return None
            try:
                return read_sam_records(records, self._merged_path, probe)
            except InputError as exc:
                raise InputError(f"view {name!r}: {exc.problem}", self._merged_path) from None
        path = self.directory / f"{name}.json"
        if not path.is_file():
            return None
        return read_sam_json(path, probe)

