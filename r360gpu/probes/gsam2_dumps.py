"""Grounded-SAM-2 JSON dumps (format ``gsam2-json``), one file per view.

``DUMP_JSON_RESULTS=True`` in its demos writes ``{"image_path", "annotations": [{"class_name", "bbox",
"segmentation": <COCO RLE, utf-8 counts string>, "score": float or [float]}], "box_format",
"img_width", "img_height"}``.  The view name is the stem of ``image_path`` when present (the demos
write fixed JSON file names), else the JSON file stem, as the public
``scripts/convert_gsam2_to_masks.py`` names its PNGs.  Annotations are kept by the prompt rule
(:mod:`r360gpu.probes.prompt_rule`).
"""
from __future__ import annotations

import json
import math
import os
from numbers import Integral, Real
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError
from r360gpu.probes import rle
from r360gpu.probes.base import SemanticPrediction
from r360gpu.probes.mask_dirs import mask_dir
from r360gpu.probes.prompt_rule import label_matches
from r360gpu.util.filehash import input_stamp

def _load_json(path: Path):
    try:
        with open(path, "rb") as f:
            return json.loads(f.read().decode("utf-8-sig"))  # a BOM is not content
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror or exc})", path) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"not utf-8 text ({exc.reason} at byte {exc.start})", path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"malformed JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})", path) from None


def _positive_int(value, what: str, path: Path) -> int:
    if not isinstance(value, Integral) or isinstance(value, bool) or value < 1:
        raise InputError(f"{what} must be a positive integer, got {value!r}", path)
    return int(value)


def _score(value, where: str, path: Path) -> float:
    """A float, or a one-element list of one (SAM2 returns (N, 1) scores)."""
    if value is None:
        return math.nan
    if isinstance(value, list):
        if len(value) != 1:
            raise InputError(f"{where}: 'score' list must have one element, got {len(value)}", path)
        value = value[0]
    if not isinstance(value, Real) or isinstance(value, bool):
        raise InputError(f"{where}: 'score' must be a number or a one-element list, got {value!r}", path)
    return float(value)


def read_gsam2_json(path: str | os.PathLike, prompt: str, probe: str = "") -> SemanticPrediction:
    """Instances of a Grounded-SAM-2 JSON dump kept by the prompt rule.

    Returns a SemanticPrediction at the file's own size (img_height x
    img_width, or the segmentation size when those are absent); a file with
    neither and no kept instance gives K = 0 at size 0 x 0.  Raises
    InputError on malformed JSON, a malformed annotation or RLE, or a
    segmentation whose size differs from the declared image size.
    """
    path = Path(path)
    data = _load_json(path)
    return _gsam2_from_data(data, prompt, probe, path)


def _gsam2_from_data(data, prompt: str, probe: str, path: Path) -> SemanticPrediction:
    if not isinstance(data, dict) or not isinstance(data.get("annotations"), list):
        raise InputError("not a Grounded-SAM-2 dump: expected an object with an 'annotations' list", path)
    size = None
    if "img_height" in data or "img_width" in data:
        size = (
            _positive_int(data.get("img_height"), "'img_height'", path),
            _positive_int(data.get("img_width"), "'img_width'", path),
        )
    masks, scores, labels = [], [], []
    for i, ann in enumerate(data["annotations"]):
        where = f"annotation {i}"
        if not isinstance(ann, dict):
            raise InputError(f"{where} is not an object", path)
        class_name = ann.get("class_name")
        if not isinstance(class_name, str):
            raise InputError(f"{where}: 'class_name' must be a string, got {class_name!r}", path)
        if not label_matches(class_name, prompt):
            continue
        seg = ann.get("segmentation")
        if not isinstance(seg, dict):
            raise InputError(f"{where}: 'segmentation' must be a COCO RLE object, got {type(seg).__name__}", path)
        try:
            mask = rle.decode(seg, path)
        except InputError as exc:
            raise InputError(f"{where}: {exc.problem}", path) from None
        if size is None:
            size = mask.shape
        elif mask.shape != size:
            raise InputError(
                f"{where}: segmentation is {mask.shape[0]}x{mask.shape[1]} but the image is {size[0]}x{size[1]}", path
            )
        masks.append(mask)
        scores.append(_score(ann.get("score"), where, path))
        labels.append(class_name)
    if size is None:
        size = (0, 0)
    stack = np.stack(masks) if masks else np.zeros((0, *size), bool)
    return SemanticPrediction(stack, np.asarray(scores, np.float32), labels, probe)


class Gsam2JsonDir:
    """Directory of Grounded-SAM-2 JSON dumps, indexed by view name on construction.

    Every ``*.json`` file is parsed once; two files claiming one view, or a
    malformed file, raise InputError.
    """

    format = "gsam2-json"

    def __init__(self, directory: str | os.PathLike):
        self.directory = mask_dir(directory)
        self._files: dict[str, tuple[Path, dict]] = {}
        # taken before reading: which file describes a view is read from the files (image_path)
        self._dir_stamp = input_stamp(self.directory)
        self._stamps: dict[Path, object] = {}
        for path in sorted(self.directory.glob("*.json")):
            self._stamps[path] = input_stamp(path)
            data = _load_json(path)
            if not isinstance(data, dict):
                raise InputError("not a Grounded-SAM-2 dump: expected a JSON object", path)
            image_path = data.get("image_path")
            name = path.stem
            if isinstance(image_path, str) and Path(image_path).stem:
                name = Path(image_path).stem
            if name in self._files:
                raise InputError(f"describes view {name!r}, as does {self._files[name][0]}", path)
            self._files[name] = (path, data)

    def names(self) -> list[str]:
        """View names found, sorted."""
        return sorted(self._files)

    def path_for(self, name: str) -> Path:
        """The file for view ``name`` (the ``<name>.json`` it would have if missing)."""
        entry = self._files.get(name)
        return entry[0] if entry else self.directory / f"{name}.json"

    def stamps(self, name: str) -> dict:
        """{path: :func:`~r360gpu.util.filehash.input_stamp`} of what :meth:`read` uses for ``name``, as
        it was when this reader parsed the folder: the view's file and the folder itself (a file added
        or removed could claim the view)."""
        path = self.path_for(name)
        return {str(self.directory): self._dir_stamp, str(path): self._stamps.get(path)}

    def read(self, name: str, prompt: str, probe: str = "") -> SemanticPrediction | None:
        """Kept instances at the file's size, or None when the view has no file."""
        entry = self._files.get(name)
        if entry is None:
            return None
        return _gsam2_from_data(entry[1], prompt, probe, entry[0])

