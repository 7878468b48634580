"""The run's caches under ``OUT/.r360cache``: per-view cells and probe outputs.

* View cache: ``views/<key>/<scene>/<method>/<view>.json``, one JSON cell per
  (method, view): the :class:`~r360gpu.metrics.record.ViewRecord`, the
  boundary table and the path of the view's picture.  A cell in memory holds
  the ViewRecord itself: it is written as a dict (:func:`cell_json`) and read
  back as a ViewRecord (:func:`cell_from_json`), here only.  ``key`` digests
  everything that changes a per-view value (version and code digest, the bundle's
  fingerprint, scoring options, probe descriptions, structural mode, depth
  mode, LPIPS model), so a changed input or option misses; the precomputed
  probe files a view was scored from are not hashed but stamped (inode, size,
  mtime, ctime) before they are read, and a cell is served only while those
  stamps hold (:func:`r360gpu.util.filehash.input_stamp`).  A view is served
  from the cache only when every method's cell is there and, when pictures
  are asked for, every cell names a picture that exists: pictures are
  outputs of the run, so a run after ``--no-pictures`` or after a picture was
  deleted recomputes the view and writes it.
* Probe cache: ``probes/``, :class:`~r360gpu.probes.cache.ProbeCache`, keyed
  by image content, so re-scoring never re-runs a probe on an unchanged image.
* Embedding JPEGs: ``embed/``, the JPEG report.html embeds each contact
  sheet as, made by the picture writer from the sheet in memory and keyed by
  the PNG's bytes (:mod:`r360gpu.report.embed`).
* Fit records: ``fits/<key>.json``, the descriptions of probes that learn
  from the scene (the appearance probe) after fitting, keyed by what the
  fit reads.  They complete the view cache key without fitting, so a run
  whose views are all cached renders nothing; a run with a view to score
  still fits first (and checks the record).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..schema import ScoredView, ViewCell
from ..util import code_id, warning_log
from ..util.filehash import changed_stamps, content_digest, decoded_digests, UNSETTLED

CACHE_DIR = ".r360cache"
#: What a view cell holds, in the view cache key: a cell written before a per-view value was added
#: lacks it, so it must miss (2: geometric records count n_no_depth_in_mask; 3: cells carry the stamps of the
#: precomputed probe files they were scored from).
CELL_FORMAT = 3


def digest(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _by_code(key: str) -> str:
    """``key`` made specific to the code running (:func:`r360gpu.util.code_id.code_digest`)."""
    return digest({"key": key, "code": code_id.code_digest()})


class RunCache:
    """The cache folder of one output folder (None out: no caching at all)."""

    def __init__(self, out: Path | None, *, force: bool = False):
        self.out = out
        self.root = out / CACHE_DIR if out is not None else None
        if force and self.root is not None and self.root.exists():
            shutil.rmtree(self.root)
        self.probes = None
        self.embed = self.root / "embed" if self.root is not None else None
        if self.root is not None:
            from ..probes.cache import ProbeCache

            self.probes = ProbeCache(self.root / "probes")

    def wrap_probe(self, probe):
        """The probe with its outputs going through the probe cache."""
        if self.probes is None:
            return probe
        from ..probes.cache import cached

        return cached(probe, self.probes)

    def load_fit(self, key: str, kind: str = "fits"):
        """The probe descriptions recorded after a fit with inputs ``key``, or None (``kind``:
        the record's sub-folder, e.g. "frames" for the frame check's verdicts)."""
        if self.root is None:
            return None
        try:
            return json.loads((self.root / kind / f"{_by_code(key)}.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    def store_fit(self, key: str, probes_desc: dict, kind: str = "fits") -> None:
        if self.root is not None:
            from ..util.atomic import write_json

            write_json(self.root / kind / f"{_by_code(key)}.json", probes_desc)

    def views(self, scene: str, key_parts: dict) -> "ViewCache | None":
        if self.root is None:
            return None
        return ViewCache(self.root / "views" / digest({"version": __version__, "code": code_id.code_digest(),
                                                       "cells": CELL_FORMAT, **key_parts})
                         / scene, self.out)


class ViewCache:
    """Per-view cells of one scene under one key."""

    def __init__(self, folder: Path, out: Path):
        self.folder = folder
        self.out = out

    def _path(self, method: str, view: str) -> Path:
        return self.folder / method / f"{view}.json"

    def _load(self, method: str, view: str) -> dict | None:
        """A cell file as written (:func:`cell_json`), its record a ViewRecord; None when missing or damaged."""
        p = self._path(method, view)
        if not p.is_file():
            return None
        try:
            return cell_from_json(json.loads(p.read_text(encoding="utf-8")))
        except (OSError, ValueError, KeyError, TypeError):
            return None  # a damaged cache entry is recomputed

    def load_cell(self, method: str, view: str) -> ViewCell | None:
        """The :class:`~r360gpu.schema.ViewCell` of (method, view), or None."""
        d = self._load(method, view)
        return None if d is None else _cell(d)

    def load_view(self, methods, view: str, *, pictures: bool) -> ScoredView | None:
        """Every method's cell of ``view`` as a :class:`~r360gpu.schema.ScoredView` (the view's
        warnings stored with its first cell), or None when any is missing (or its picture is, or a
        precomputed probe file it was scored from has changed since: the cells' ``inputs``)."""
        cells, inputs, warnings = {}, {}, None
        for m in methods:
            d = self._load(m, view)
            if not d:
                return None
            if pictures and not (d.get("picture") and (self.out / d["picture"]).is_file()):
                return None
            cells[m] = _cell(d)
            inputs.update(cells[m].inputs)
            if warnings is None:
                warnings = d.get("warnings")
        return None if changed_stamps(inputs) else ScoredView(cells, warnings)

    def load_scored(self, methods, controls, view: str, *, pictures: bool) -> ScoredView | None:
        """Every cell of ``view`` (the methods', whose pictures are checked, and the controls'), or None."""
        scored = self.load_view(methods, view, pictures=pictures)
        if scored is None:
            return None
        ctl = self.load_view(controls, view, pictures=False)
        return None if ctl is None else ScoredView({**scored.cells, **ctl.cells}, scored.warnings)

    def store_view(self, view: str, scored: ScoredView, changed: list) -> bool:
        """Store every cell of ``view`` (a :class:`~r360gpu.schema.ScoredView`; its warnings go into
        the first cell's file) unless ``changed`` names an input whose decoded bytes are not
        those the key was computed from (:func:`changed_inputs`), or a precomputed probe file the
        view was scored from has another stamp now than before it was read (the cells' ``inputs``);
        then warn and store nothing.  A probe file written within the last 2 s (its stamp proves
        nothing yet) keeps the view out of the cache without a warning.  True when stored."""
        inputs: dict = {}
        for cell in scored.cells.values():
            inputs.update(cell.inputs)
        if any(s == UNSETTLED for s in inputs.values()):
            return False
        changed = list(changed) + changed_stamps(inputs)
        if changed:
            for f in changed:
                warning_log.warn(f"changed while the run read it: view {view!r} was scored from other bytes "
                                 f"than the run's cache key says, so its result is not cached (the next run "
                                 f"scores it again)", file=f, view=view)
            return False
        for i, (m, cell) in enumerate(scored.cells.items()):
            self.store(m, view, cell, scored.warnings if i == 0 else None)
        return True

    def store(self, method: str, view: str, cell: ViewCell, warnings: dict | None = None) -> None:
        from ..util.atomic import write_json

        # compact (no indent): written for every method and view, read back by this class only;
        # a damaged cell is recomputed
        write_json(self._path(method, view), cell_json(cell, warnings), allow_nan=False, sync=False, indent=None)


def cell_json(cell: ViewCell, warnings: dict | None = None) -> dict:
    """A :class:`~r360gpu.schema.ViewCell` as a cache file holds it: its ViewRecord as a dict
    (:meth:`~r360gpu.metrics.record.ViewRecord.to_dict`), "inputs" only when some file was read,
    and the view's ``warnings`` when given (its first cell's file holds them)."""
    d = {"record": cell.record.to_dict(), "boundary": cell.boundary, "picture": cell.picture}
    if cell.inputs:
        d["inputs"] = cell.inputs
    if warnings is not None:
        d["warnings"] = warnings
    return d


def cell_from_json(d: dict) -> dict:
    """A cell file read back (:func:`cell_json`): its record a ViewRecord again (InputError, a ValueError,
    when it is not one)."""
    from ..metrics.record import ViewRecord

    return {**d, "record": ViewRecord.from_dict(d["record"])}


def _cell(d: dict) -> ViewCell:
    return ViewCell(d["record"], d.get("boundary"), d.get("picture"), d.get("inputs") or {})


def fingerprint(bundle, sources, digests: dict | None = None) -> str | None:
    """The bundle's file fingerprint, or for scenes built from objects a hash of
    what is scored: the sources' descriptions and, for Gaussians in memory,
    their values; the cameras; the target masks.  None when a source's content
    cannot be known without reading it back (renders held on the device): such
    a scene is scored anew every run, and nothing of it is cached.

    sources: [pre, reference or None, *methods, *own pres], the opened sources.
    digests: the bundle's :meth:`~r360gpu.bundle.Bundle.file_digests`, when the run keeps them.
    """
    from ..bundle import is_from_objects
    from ..render.sources import SceneSource

    if not is_from_objects(bundle):
        return bundle.fingerprint() if digests is None else bundle.fingerprint_of(digests)
    h = hashlib.sha256()
    for s in sources:
        if s is not None and s.kind == "device":
            return None
        h.update(json.dumps(None if s is None else s.describe(), sort_keys=True, default=str).encode())
        # the description holds the path and count, not the values: two edits of the same size must not
        # share results, whether the Gaussians are in memory or a file edited in place
        for part in _content(s, bundle.views):
            h.update(part.encode())
        h.update(repr(s.background if isinstance(s, SceneSource) else None).encode())
    for v in bundle.views:
        cam = (bundle.cameras or {}).get(v)
        if cam is not None:  # every value exactly (repr(float) round-trips)
            h.update(np.asarray(cam.R, np.float64).tobytes() + np.asarray(cam.t, np.float64).tobytes())
            h.update(repr((cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)).encode())
        m = bundle.masks.get(v)
        h.update(np.ascontiguousarray(m).tobytes() if isinstance(m, np.ndarray) else str(m).encode())
    _update_target(h, bundle.target)
    return h.hexdigest()


def _content(source, views) -> list[str]:
    """Digests of what an opened source holds: its Gaussians' values (in memory), its splat file's
    bytes, or its renderings' bytes at ``views`` (a missing file hashed as missing)."""
    from ..render.sources import RendersSource, SceneSource

    def of(path) -> str:
        try:
            return content_digest(path)
        except OSError:
            return f"missing {path}"

    if source is None:
        return []
    if isinstance(source, SceneSource):
        return [source.gaussians.content_digest() if source.in_memory else of(source.path)]
    if not isinstance(source, RendersSource):
        return []
    reader = source.reader
    out = []
    for v in views:
        for lookup in (reader.rgb_path, reader.depth_path) if reader.has_depth else (reader.rgb_path,):
            try:
                out.append(of(lookup(v)))
            except InputError:
                out.append(f"no file for {v}")
    return out


def _update_target(h, spec) -> None:
    """Add a declared target (indices, box, masks of some views) to a from-objects fingerprint."""
    if spec is None:
        h.update(b"no target")
        return
    for name in ("indices", "prop", "box", "masks"):
        h.update(name.encode())
        _update_value(h, getattr(spec, name))  # a TargetSpec's fields


def _update_value(h, value) -> None:
    """Every value exactly: arrays by their bytes, dicts by sorted key, dataclasses (a Box) field by field."""
    if isinstance(value, dict):
        for k in sorted(value, key=str):
            h.update(repr(k).encode())
            _update_value(h, value[k])
    elif isinstance(value, np.ndarray):
        h.update(str((value.dtype, value.shape)).encode() + np.ascontiguousarray(value).tobytes())
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        h.update(type(value).__name__.encode())
        for f in dataclasses.fields(value):
            _update_value(h, getattr(value, f.name))
    else:
        h.update(repr(value).encode())


def changed_inputs(keyed: dict | None, files: list, decoded: dict | None = None) -> list[str]:
    """The files among ``files`` whose bytes, as decoded in this run, differ from those the cache key
    was computed from.

    keyed: {path: digest} of the key (:meth:`~r360gpu.bundle.Bundle.file_digests`; None: scenes
    from objects, nothing to check).  decoded: {absolute path: digest} of what was decoded (default:
    what :func:`r360gpu.util.filehash.read_file` read in this process; a Ray worker sends its own).
    """
    if keyed is None:
        return []
    absolute = {f: os.path.abspath(f) for f in files}
    decoded = decoded_digests(absolute.values()) if decoded is None else decoded
    return [f for f, a in absolute.items() if a in decoded and decoded[a] != keyed.get(f)]
