"""Probes that serve precomputed masks, imported per view from folders of files.

The file formats (one file or folder per view; a view is named by its image file stem) are read by
one module each: ``gsam2-json`` (:mod:`.gsam2_dumps`), ``png`` (:mod:`.mask_dirs`), ``sam-json``
(:mod:`.sam_records`) and ``sam-amg`` (:mod:`.amg_folders`).  This module picks the reader of a
folder, serves each view the masks of the rendering it is (pre / post / ref, or one method's post)
at the view's size, and counts what it met.

What the public evaluation code (github simonakocour/anything_left, commit dd0aad8) does with these
layouts, and which we follow:

* ``remove360/evaluation/semantic.py``: per scene, the view list is the ``*.png`` names of the
  ground-truth ``masks/`` folder; the same file name is looked up in ``gsam2/before/mask/`` and
  ``gsam2/after/mask/``, read with ``cv2.imread(..., IMREAD_GRAYSCALE)`` and binarised with ``> 0``;
  a missing file becomes an all-zero mask; masks are resized to the largest size among (GT, before,
  after) with torch ``"nearest"``.
* ``scripts/convert_gsam2_to_masks.py`` makes those PNGs from Grounded-SAM-2 dumps: keeps
  annotations with ``class_name.lower() == prompt.lower()`` (all of them for an empty prompt), ORs
  them, names the PNG after the stem of ``image_path`` (else the JSON stem), and writes no PNG when
  nothing is kept -- hence "missing file = no detection".
* ``remove360/evaluation/sam.py`` resizes SAM masks with ``cv2.INTER_NEAREST`` to the GT mask size.

Masks whose size differs from the rendering are resized with nearest neighbour (source index
``floor(i * in / out)``, the convention of ``cv2.INTER_NEAREST`` and torch's ``"nearest"``); the
first resize per probe raises one :class:`R360Warning`.  A missing file is "no detection" (an empty
prediction or mask set); missing files are counted in ``probe.stats``, and the first one per probe
raises one warning.
"""
from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from r360gpu.errors import InputError, R360Warning
from r360gpu.util import warning_log
from r360gpu.util.resize import resize_nearest  # the project's nearest rule
from r360gpu.probes import rle
from r360gpu.probes.amg_folders import SamAmgDir, is_amg_dir
from r360gpu.probes.base import (
    RENDERINGS,
    MaskSet,
    ProbeView,
    SemanticPrediction,
    SemanticProbe,
    StructuralProbe,
)
from r360gpu.probes.gsam2_dumps import Gsam2JsonDir
from r360gpu.probes.mask_dirs import PngMaskDir, mask_dir
from r360gpu.probes.prompt_rule import PROMPT_RULE
from r360gpu.probes.sam_records import SamJsonDir

__all__ = [
    "REMOVE360_LAYOUT",
    "ImportStats",
    "PrecomputedSemanticProbe",
    "PrecomputedStructuralProbe",
    "remove360_sources",
]

#: Public Remove360 evaluation layout, relative to a scene directory
#: (simonakocour/anything_left: remove360/evaluation/semantic.py, sam.py).
REMOVE360_LAYOUT = {
    "semantic": {"pre": "gsam2/before/mask", "post": "gsam2/after/mask"},
    "structural": {"post": "sam/after"},
}


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

    def input_stamps(self, name: str, rendering: str | None, method: str | None = None) -> dict:
        """The stamps of the file(s) :meth:`predict` reads for the view (:meth:`Probe.input_stamps`)."""
        return self._source_of(name, rendering, method).stamps(name)

    def _source_for(self, view: ProbeView):
        return self._source_of(view.name, view.rendering, view.method)

    def _source_of(self, name: str, rendering: str | None, method: str | None):
        if rendering is None:
            raise InputError(
                f"view {name!r}: probe {self.name!r} reads precomputed masks and needs to know "
                f"which rendering ({'/'.join(RENDERINGS)}) the view is"
            )
        source = None
        if rendering == "post" and method:
            # Masks imported for this method's edit, when given, win over plain "post".
            source = self.sources.get(f"post/{method}")
        if source is None:
            source = self.sources.get(rendering)
        if source is None:
            have = ", ".join(f"{r}={getattr(s, 'directory', s)}" for r, s in sorted(self.sources.items()))
            raise InputError(f"probe {self.name!r} has no precomputed masks for the {rendering!r} rendering "
                             f"(it has {have}); give them, e.g. {rendering}=DIR in the probe spec")
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
    path = mask_dir(directory)
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
    scene = mask_dir(scene_dir)
    return {
        axis: {r: scene / rel for r, rel in layout.items() if (scene / rel).is_dir()}
        for axis, layout in REMOVE360_LAYOUT.items()
    }
