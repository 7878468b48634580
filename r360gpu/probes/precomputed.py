"""Importers of precomputed probe masks, and probes that serve them.

Supported formats (one file per view; a view is named by its image file stem):

* ``gsam2-json`` -- Grounded-SAM-2 JSON dumps (``DUMP_JSON_RESULTS=True`` in
  its demos): ``{"image_path", "annotations": [{"class_name", "bbox",
  "segmentation": <COCO RLE, utf-8 counts string>, "score": float or [float]}],
  "box_format", "img_width", "img_height"}``.  The view name is the stem of
  ``image_path`` when present (the demos write fixed JSON file names), else
  the JSON file stem.
* ``png`` -- one mask image per view, ``<name>.png``, any non-zero pixel is
  the mask (colour images: any non-zero colour channel; alpha is ignored).
  This is the public Remove360 evaluation layout ``gsam2/{before,after}/mask/``.
* ``sam-json`` -- SAM automatic-mask records per view, ``<name>.json``: a list
  of ``{"segmentation", "area", "bbox", ...}`` where ``segmentation`` is a
  nested row-major H x W list of 0/1 (or true/false) or a COCO RLE; the key
  ``"mask"`` is accepted in place of ``"segmentation"``; ``predicted_iou``, when
  every record has it, becomes the scores.  ``area`` and ``bbox`` are not
  used.  A ``merged.json`` mapping image name -> record list, when present,
  is used instead of the per-view files (image names lose a .png/.jpg/.jpeg
  extension).  This is the public layout ``sam/after/``.

Prompt rule (``gsam2-json``): the prompt is split at '.' into phrases
(Grounding DINO's prompt syntax, e.g. ``"sofa."`` or ``"sofa. couch."``); the
class name and each phrase are lower-cased, stripped and have inner
whitespace runs collapsed to one space; an annotation is kept when its class
name equals one of the phrases.  Substrings do not match ("sofa" does not
keep "sofa cushion").  A prompt with no phrase keeps every annotation, as the
public converter does.  PNG masks are already per-prompt: the prompt becomes
their label.

What the public evaluation code (github simonakocour/anything_left, commit
dd0aad8) does with these layouts, and which we follow:

* ``remove360/evaluation/semantic.py``: per scene, the view list is the
  ``*.png`` names of the ground-truth ``masks/`` folder; the same file name
  is looked up in ``gsam2/before/mask/`` and ``gsam2/after/mask/``, read with
  ``cv2.imread(..., IMREAD_GRAYSCALE)`` and binarised with ``> 0``; a missing
  file becomes an all-zero mask; masks are resized to the largest size among
  (GT, before, after) with torch ``"nearest"``.
* ``scripts/convert_gsam2_to_masks.py`` makes those PNGs from Grounded-SAM-2
  dumps: keeps annotations with ``class_name.lower() == prompt.lower()``
  (all of them for an empty prompt), ORs them, names the PNG after the stem
  of ``image_path`` (else the JSON stem), and writes no PNG when nothing is
  kept -- hence "missing file = no detection".
* ``scripts/run_sam_on_rgb.py`` writes ``sam/after/<stem>.json`` as a list of
  ``{"segmentation": bool_mask.tolist(), "area", "bbox"}``;
  ``remove360/utils/io.py:load_sam_data`` reads ``merged.json`` if present,
  else every ``*.json`` keyed by stem; ``remove360/evaluation/sam.py`` takes
  ``"mask"`` or ``"segmentation"`` and resizes with ``cv2.INTER_NEAREST`` to
  the GT mask size.

Masks whose size differs from the rendering are resized with nearest
neighbour (source index ``floor(i * in / out)``, the convention of
``cv2.INTER_NEAREST`` and torch's ``"nearest"``); the first resize per probe
raises one :class:`R360Warning`.  A missing file is "no detection" (an empty
prediction or mask set); missing files are counted in ``probe.stats``, and
the first one per probe raises one warning.
"""
from __future__ import annotations

import json
import math
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from numbers import Integral, Real
from pathlib import Path

import cv2
import numpy as np

from r360gpu.errors import InputError, R360Warning
from r360gpu.util import warning_log
from r360gpu.util.resize import resize_nearest  # re-exported: the project's nearest rule
from r360gpu.probes import rle, sam_json
from r360gpu.probes.base import (
    RENDERINGS,
    MaskSet,
    ProbeView,
    SemanticPrediction,
    SemanticProbe,
    StructuralProbe,
)

__all__ = [
    "PROMPT_RULE",
    "REMOVE360_LAYOUT",
    "prompt_phrases",
    "label_matches",
    "resize_nearest",
    "read_gsam2_json",
    "read_sam_records",
    "read_sam_json",
    "read_mask_png",
    "Gsam2JsonDir",
    "PngMaskDir",
    "SamJsonDir",
    "ImportStats",
    "PrecomputedSemanticProbe",
    "PrecomputedStructuralProbe",
    "remove360_sources",
]

PROMPT_RULE = (
    "class_name equals one '.'-separated prompt phrase after lower-casing, stripping "
    "and collapsing whitespace; an empty prompt keeps all"
)

#: Public Remove360 evaluation layout, relative to a scene directory
#: (simonakocour/anything_left: remove360/evaluation/semantic.py, sam.py).
REMOVE360_LAYOUT = {
    "semantic": {"pre": "gsam2/before/mask", "post": "gsam2/after/mask"},
    "structural": {"post": "sam/after"},
}

_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _normalise(text: str) -> str:
    return re.sub(r"\s+", " ", text.strip().lower())


def prompt_phrases(prompt: str) -> list[str]:
    """Normalised phrases of a prompt (see the prompt rule in the module docstring)."""
    return [p for p in (_normalise(part) for part in prompt.split(".")) if p]


def label_matches(class_name: str, prompt: str) -> bool:
    """True when ``class_name`` is kept for ``prompt`` under the prompt rule."""
    phrases = prompt_phrases(prompt)
    return not phrases or _normalise(class_name) in phrases


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


def read_mask_png(path: str | os.PathLike) -> np.ndarray:
    """bool (H, W) from a mask image: non-zero = mask (colour: any colour channel;
    alpha ignored).  The same reader as the target masks (:func:`r360gpu.io.load_mask`)."""
    from ..io.masks import load_mask

    return load_mask(path)


def _check_dir(directory: str | os.PathLike) -> Path:
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("mask directory does not exist", directory)
    return directory


def _strip_image_suffix(name: str) -> str:
    lower = name.lower()
    for suffix in _IMAGE_SUFFIXES:
        if lower.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return name


class Gsam2JsonDir:
    """Directory of Grounded-SAM-2 JSON dumps, indexed by view name on construction.

    Every ``*.json`` file is parsed once; two files claiming one view, or a
    malformed file, raise InputError.
    """

    format = "gsam2-json"

    def __init__(self, directory: str | os.PathLike):
        self.directory = _check_dir(directory)
        self._files: dict[str, tuple[Path, dict]] = {}
        for path in sorted(self.directory.glob("*.json")):
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

    def read(self, name: str, prompt: str, probe: str = "") -> SemanticPrediction | None:
        """Kept instances at the file's size, or None when the view has no file."""
        entry = self._files.get(name)
        if entry is None:
            return None
        return _gsam2_from_data(entry[1], prompt, probe, entry[0])


class PngMaskDir:
    """Directory of per-view mask images ``<name>.png`` (non-zero = mask)."""

    format = "png"

    def __init__(self, directory: str | os.PathLike):
        self.directory = _check_dir(directory)

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.directory.glob("*.png"))

    def path_for(self, name: str) -> Path:
        return self.directory / f"{name}.png"

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


class SamJsonDir:
    """Directory of SAM automatic-mask JSON: ``merged.json`` if present, else ``<name>.json``."""

    format = "sam-json"

    def __init__(self, directory: str | os.PathLike):
        self.directory = _check_dir(directory)
        self._merged_path = self.directory / "merged.json"
        self._merged: dict[str, list] | None = None
        if self._merged_path.is_file():
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


AMG_METADATA = "metadata.csv"
# Header of segment-anything's scripts/amg.py write_masks_to_folder (one row per mask <id>.png).
AMG_HEADER = ("id,area,bbox_x0,bbox_y0,bbox_w,bbox_h,point_input_x,point_input_y,predicted_iou,"
              "stability_score,crop_box_x0,crop_box_y0,crop_box_w,crop_box_h")


def is_amg_view_folder(folder: Path) -> bool:
    """A folder as segment-anything's ``scripts/amg.py`` writes per image: ``metadata.csv`` + ``<i>.png``."""
    return (folder / AMG_METADATA).is_file()


def is_amg_dir(directory: str | os.PathLike) -> bool:
    """A directory of amg.py output (one sub-folder per image holding ``metadata.csv``), without JSON files."""
    d = Path(directory)
    if not d.is_dir() or any(d.glob("*.json")):
        return False
    return any(p.is_dir() and is_amg_view_folder(p) for p in d.iterdir())


def read_amg_folder(folder: str | os.PathLike, probe: str = "") -> MaskSet:
    """The masks of one image as ``scripts/amg.py`` writes them (binary-mask mode): ``metadata.csv``
    (header :data:`AMG_HEADER`, one row per mask) and ``<id>.png`` per row; scores = predicted_iou."""
    folder = Path(folder)
    meta = folder / AMG_METADATA
    try:
        lines = [ln.strip() for ln in meta.read_text(encoding="utf-8").splitlines() if ln.strip()]
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", meta) from None
    except UnicodeDecodeError:
        raise InputError("not a text file (expected SAM amg.py metadata.csv)", meta) from None
    if not lines or lines[0] != AMG_HEADER:
        raise InputError(f"not SAM amg.py metadata (the first line must be {AMG_HEADER!r})", meta)
    cols = AMG_HEADER.split(",")
    i_id, i_iou = cols.index("id"), cols.index("predicted_iou")
    masks, scores = [], []
    for n, line in enumerate(lines[1:], start=2):
        row = line.split(",")
        if len(row) != len(cols):
            raise InputError(f"line {n} has {len(row)} fields, the header {len(cols)}", meta)
        try:
            mid, iou = int(row[i_id]), float(row[i_iou])
        except ValueError:
            raise InputError(f"line {n}: id must be an integer and predicted_iou a number", meta) from None
        png = folder / f"{mid}.png"
        if not png.is_file():
            raise InputError(f"mask {png.name} listed on line {n} of {AMG_METADATA} is missing", png)
        m = read_mask_png(png)
        if masks and m.shape != masks[0].shape:
            raise InputError(f"mask is {m.shape[1]}x{m.shape[0]}, {masks[0].shape[1]}x{masks[0].shape[0]} "
                             f"for the first mask of the folder", png)
        masks.append(m)
        scores.append(iou)
    if not masks:
        return MaskSet(np.zeros((0, 0, 0), bool), None, probe)
    return MaskSet(np.stack(masks), np.asarray(scores, np.float32), probe)


class SamAmgDir:
    """Directory of segment-anything ``scripts/amg.py`` output: ``<name>/metadata.csv`` and
    ``<name>/<i>.png`` per view (its default, binary-mask mode)."""

    format = "sam-amg"

    def __init__(self, directory: str | os.PathLike):
        self.directory = _check_dir(directory)

    def names(self) -> list[str]:
        return sorted(p.name for p in self.directory.iterdir() if p.is_dir() and is_amg_view_folder(p))

    def path_for(self, name: str) -> Path:
        return self.directory / name / AMG_METADATA

    def read(self, name: str, probe: str = "") -> MaskSet | None:
        folder = self.directory / name
        if not folder.is_dir():
            return None
        if not is_amg_view_folder(folder):
            raise InputError(f"SAM amg.py folder of view {name!r} has no {AMG_METADATA}", folder)
        return read_amg_folder(folder, probe)


def sam_source(directory: str | os.PathLike) -> "SamJsonDir | SamAmgDir":
    """The reader of a directory of SAM masks: amg.py folders, else JSON (``merged.json`` / ``<name>.json``)."""
    return SamAmgDir(directory) if is_amg_dir(directory) else SamJsonDir(directory)


@dataclass
class ImportStats:
    """What a precomputed probe met: views without a file, and resized files.

    Entries are ``"<rendering>/<view name>"``, each recorded once.
    """

    missing: list[str] = field(default_factory=list)
    resized: list[str] = field(default_factory=list)

    @property
    def missing_count(self) -> int:
        return len(self.missing)

    @property
    def resized_count(self) -> int:
        return len(self.resized)

    def as_dict(self) -> dict:
        return {
            "missing_count": self.missing_count,
            "missing": list(self.missing),
            "resized_count": self.resized_count,
            "resized": list(self.resized),
        }


class _Importer:
    """Shared part of the precomputed probes: source lookup, resizing, counting."""

    cacheable = False

    def _init(self, sources: Mapping[str, object], name: str) -> None:
        if not sources:
            raise ValueError("give at least one source (rendering -> directory)")
        for rendering in sources:
            if rendering not in RENDERINGS and not (rendering.startswith("post/") and len(rendering) > 5):
                raise ValueError(f"source keys must be among {RENDERINGS} or 'post/METHOD', got {rendering!r}")
        self.sources = dict(sources)
        self._name = name
        self.stats = ImportStats()
        self._warned_resize = False
        self._warned_missing = False

    @property
    def name(self) -> str:
        return self._name

    @property
    def missing_count(self) -> int:
        """Number of (rendering, view) pairs whose mask file was missing."""
        return self.stats.missing_count

    def _source_params(self) -> dict:
        formats = sorted({s.format for s in self.sources.values()})
        return {
            "source": "precomputed",
            "format": formats[0] if len(formats) == 1 else formats,
            "paths": {r: str(s.directory) for r, s in sorted(self.sources.items())},
        }

    def _source_for(self, view: ProbeView):
        if view.rendering is None:
            raise InputError(
                f"view {view.name!r}: probe {self.name!r} reads precomputed masks and needs to know "
                f"which rendering ({'/'.join(RENDERINGS)}) the view is"
            )
        source = None
        if view.rendering == "post" and view.method:
            # Masks imported for this method's edit, when given, win over plain "post".
            source = self.sources.get(f"post/{view.method}")
        if source is None:
            source = self.sources.get(view.rendering)
        if source is None:
            have = ", ".join(f"{r}={getattr(s, 'directory', s)}" for r, s in sorted(self.sources.items()))
            raise InputError(f"probe {self.name!r} has no precomputed masks for the {view.rendering!r} rendering "
                             f"(it has {have}); give them, e.g. {view.rendering}=DIR in the probe spec")
        return source

    def _note_missing(self, view: ProbeView, source) -> None:
        entry = f"{view.rendering}/{view.method + '/' if view.method else ''}{view.name}"
        if entry not in self.stats.missing:
            self.stats.missing.append(entry)
            warning_log.count("missing_probe_files", f"{self.name}:{source.directory}")
        if not self._warned_missing:
            self._warned_missing = True
            warnings.warn(
                f"{source.path_for(view.name)}: no precomputed mask for view {view.name!r}; counted as no "
                f"detection (further missing files of probe {self.name!r} are counted in results.json "
                f"warning_counts, not warned)",
                R360Warning,
                stacklevel=4,
            )

    def _fit(self, masks: np.ndarray, view: ProbeView, source) -> np.ndarray:
        """(K, h, w) masks resized to the view's (H, W), recorded and warned once."""
        if masks.shape[1:] == view.size:
            return masks
        if masks.shape[0] > 0:
            entry = f"{view.rendering}/{view.name}"
            if entry not in self.stats.resized:
                self.stats.resized.append(entry)
            if not self._warned_resize:
                self._warned_resize = True
                warnings.warn(
                    f"{source.path_for(view.name)}: masks are {masks.shape[1]}x{masks.shape[2]} but the rendering "
                    f"is {view.height}x{view.width}; resized with nearest neighbour (further resizes of probe "
                    f"{self.name!r} are counted, not warned)",
                    R360Warning,
                    stacklevel=4,
                )
        return resize_nearest(masks, view.size)


class PrecomputedSemanticProbe(_Importer, SemanticProbe):
    """Semantic probe serving imported instances: ``gsam2-json`` or ``png`` sources.

    sources: rendering ("pre"/"post"/"ref") -> :class:`Gsam2JsonDir` or
    :class:`PngMaskDir`.  ``predict`` returns, per view, the instances kept by
    the prompt rule at the view's size; a missing file gives an empty
    prediction and is counted in ``stats``.
    """

    def __init__(self, sources: Mapping[str, Gsam2JsonDir | PngMaskDir], name: str = "gsam2-precomputed"):
        self._init(sources, name)

    @classmethod
    def from_dirs(
        cls,
        dirs: Mapping[str, str | os.PathLike],
        format: str = "auto",
        name: str = "gsam2-precomputed",
    ) -> "PrecomputedSemanticProbe":
        """Build from rendering -> directory.  format: "gsam2-json", "png" or
        "auto" (a directory with ``*.json`` files and no ``*.png`` is
        gsam2-json, one with ``*.png`` and no ``*.json`` is png)."""
        return cls({r: _semantic_source(d, format) for r, d in dirs.items()}, name)

    def params(self) -> dict:
        params = self._source_params()
        params["prompt_rule"] = PROMPT_RULE
        return params

    def predict(self, views: Sequence[ProbeView], prompt: str) -> list[SemanticPrediction]:
        """One SemanticPrediction per view, at the view's size."""
        out = []
        for view in views:
            source = self._source_for(view)
            with rle.size_limit(_MASK_SIZE_FACTOR * view.height * view.width):  # bounded before decoding
                pred = source.read(view.name, prompt, self.name)
            if pred is None:
                self._note_missing(view, source)
                out.append(SemanticPrediction.empty(view.height, view.width, self.name))
                continue
            masks = self._fit(pred.masks, view, source)
            out.append(SemanticPrediction(masks, pred.scores, pred.labels, self.name))
        return out


class PrecomputedStructuralProbe(_Importer, StructuralProbe):
    """Structural probe serving imported SAM automatic masks (:class:`SamJsonDir` sources)."""

    def __init__(self, sources: Mapping[str, SamJsonDir], name: str = "sam-precomputed"):
        self._init(sources, name)

    @classmethod
    def from_dirs(cls, dirs: Mapping[str, str | os.PathLike], name: str = "sam-precomputed") -> "PrecomputedStructuralProbe":
        """Build from rendering -> directory of SAM JSON files."""
        return cls({r: sam_source(d) for r, d in dirs.items()}, name)

    def params(self) -> dict:
        return self._source_params()

    def predict(self, views: Sequence[ProbeView]) -> list[MaskSet]:
        """One MaskSet per view, at the view's size."""
        out = []
        for view in views:
            source = self._source_for(view)
            with rle.size_limit(_MASK_SIZE_FACTOR * view.height * view.width):
                found = source.read(view.name, self.name)
            if found is None:
                self._note_missing(view, source)
                out.append(MaskSet.empty(view.height, view.width, self.name))
                continue
            out.append(MaskSet(self._fit(found.masks, view, source), found.scores, self.name))
        return out


#: An imported mask may have up to this many times the view's pixels (masks of a 2x larger image
#: are resized to the view); an RLE claiming more is refused before it is decoded.
_MASK_SIZE_FACTOR = 4


def _semantic_source(directory: str | os.PathLike, format: str) -> Gsam2JsonDir | PngMaskDir:
    if format == "gsam2-json":
        return Gsam2JsonDir(directory)
    if format == "png":
        return PngMaskDir(directory)
    if format != "auto":
        raise ValueError(f"format must be 'auto', 'gsam2-json' or 'png', got {format!r}")
    path = _check_dir(directory)
    has_json = any(path.glob("*.json"))
    has_png = any(path.glob("*.png"))
    if has_json and not has_png:
        return Gsam2JsonDir(path)
    if has_png and not has_json:
        return PngMaskDir(path)
    why = "both .json and .png files" if has_json else "neither .json nor .png files"
    raise InputError(f"cannot tell the mask format: the directory holds {why}; name the format", path)


def remove360_sources(scene_dir: str | os.PathLike) -> dict[str, dict[str, Path]]:
    """Existing precomputed-mask directories of a scene in the public Remove360 layout.

    Returns ``{"semantic": {rendering: dir}, "structural": {rendering: dir}}``
    with only the directories of :data:`REMOVE360_LAYOUT` that exist.
    Raises InputError when ``scene_dir`` is not a directory.
    """
    scene = _check_dir(scene_dir)
    return {
        axis: {r: scene / rel for r, rel in layout.items() if (scene / rel).is_dir()}
        for axis, layout in REMOVE360_LAYOUT.items()
    }
