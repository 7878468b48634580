"""results.json and results.csv: writing, reading back, and reading values out.

results.json is the one document an evaluation run produces (built by
`r360gpu.pipeline.results_doc`, which states its keys; schema tag :data:`RESULTS_SCHEMA`)::

    {"schema": "r360gpu.results/1", "r360gpu_version", "created", "adapter", "options", "probes",
     "scenes": {SCENE: {"prompt", "n_views", "views", "reference", "excluded_views",
                        "methods": {METHOD: {"axes": {...}, "views": [ViewRecord.to_dict(), ...],
                                             "pictures": {VIEW: relpath}, "plot": relpath}}}},
     "aggregate": aggregate_tables(...), "sensitivity": {"xi": ..., "boundary": ...}}

It is written as strict JSON: non-finite floats (an identical-image PSNR is
+inf) are tagged ``{"__float__": "inf"}`` as in the per-view records
(:mod:`r360gpu.metrics.json_values`), so ``json.dumps(..., allow_nan=False)``
succeeds and any JSON reader accepts the file.  :func:`read_results` returns
the document as stored (tags kept); :func:`number` turns a stored value back
into a float.

results.csv has one row per (scene, method, view) with the per-view values;
see :func:`results_csv_rows` for the columns.
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from ..errors import InputError
from ..metrics import json_values
from ..protocol import RESULTS_SCHEMA, STRUCTURAL_MODES  # RESULTS_SCHEMA: format tag of results.json
from ..util.atomic import write_bytes, write_text

RESULTS_JSON = "results.json"
RESULTS_CSV = "results.csv"


# -- reading values out of a results document ---------------------------------

def number(value) -> float | None:
    """A stored number as a float: None stays None, tagged non-finite floats
    (``{"__float__": "inf"}``) become ``inf`` / ``nan``; anything else that is
    not a number gives None (the renderers show it as missing)."""
    if value is None or isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, dict):
        try:
            return json_values.dec_float(value)
        except InputError:
            return None
    return None


def scene_names(results: dict) -> list[str]:
    """Scenes in display order: ``aggregate["scenes"]`` when present, else the document's order."""
    scenes = results.get("scenes") or {}
    order = [s for s in (results.get("aggregate") or {}).get("scenes", []) if s in scenes]
    return order + [s for s in scenes if s not in order]


def method_names(results: dict) -> list[str]:
    """Methods in display order: ``aggregate["methods"]`` when present, then any
    other method in order of first appearance over the scenes."""
    order = list((results.get("aggregate") or {}).get("methods", []))
    for scene in (results.get("scenes") or {}).values():
        for m in (scene.get("methods") or {}):
            if m not in order:
                order.append(m)
    return order


def method_entry(results: dict, scene: str, method: str) -> dict | None:
    """``results["scenes"][scene]["methods"][method]`` or None when the method skipped the scene."""
    return ((results.get("scenes") or {}).get(scene, {}).get("methods") or {}).get(method)


def structural_mode(results: dict, scene: str) -> str:
    """"reference" or "reference_free" for one scene.

    Read from the per-view structural records when there are any (they carry
    the mode used); otherwise inferred from the scene's ``reference`` flag and
    the ``options.reference_free`` switch.
    """
    s = (results.get("scenes") or {}).get(scene, {})
    for entry in (s.get("methods") or {}).values():
        for rec in entry.get("views") or []:
            for sv in (rec.get("structural") or {}).values():
                if sv.get("mode") in STRUCTURAL_MODES:
                    return sv["mode"]
    forced = bool((results.get("options") or {}).get("reference_free", False))
    return "reference" if s.get("reference") and not forced else "reference_free"


def structural_modes(results: dict) -> set[str]:
    """The structural modes used over all scenes."""
    return {structural_mode(results, s) for s in scene_names(results)}


# -- checking ------------------------------------------------------------------

def check_results(doc) -> list[str]:
    """Problems that stop the report layer from reading ``doc`` (empty when usable).

    Checks the schema tag and the nesting the renderers walk: ``scenes`` is an
    object of scene objects, each with a ``methods`` object of method objects
    that have an ``axes`` object and a ``views`` list of objects; the optional
    ``aggregate``, ``sensitivity``, ``probes``, ``options``, ``adapter`` are
    objects when present.
    """
    if not isinstance(doc, dict):
        return [f"expected a JSON object at the top level, got {type(doc).__name__}"]
    problems: list[str] = []
    schema = doc.get("schema")
    if schema != RESULTS_SCHEMA:
        problems.append(f"schema is {schema!r}, expected {RESULTS_SCHEMA!r}")
    scenes = doc.get("scenes")
    if not isinstance(scenes, dict):
        problems.append("'scenes' must be an object of scenes")
        scenes = {}
    for sname, scene in scenes.items():
        if not isinstance(scene, dict):
            problems.append(f"scene {sname!r}: expected an object")
            continue
        methods = scene.get("methods")
        if not isinstance(methods, dict):
            problems.append(f"scene {sname!r}: 'methods' must be an object")
            continue
        for mname, entry in methods.items():
            where = f"scene {sname!r}, method {mname!r}"
            if not isinstance(entry, dict):
                problems.append(f"{where}: expected an object")
                continue
            if not isinstance(entry.get("axes"), dict):
                problems.append(f"{where}: 'axes' must be an object")
            views = entry.get("views")
            if not isinstance(views, list) or not all(isinstance(v, dict) for v in views):
                problems.append(f"{where}: 'views' must be a list of view records")
            for key in ("pictures",):
                if key in entry and not isinstance(entry[key], dict):
                    problems.append(f"{where}: '{key}' must be an object")
    for key in ("aggregate", "sensitivity", "probes", "options", "adapter"):
        if key in doc and doc[key] is not None and not isinstance(doc[key], dict):
            problems.append(f"'{key}' must be an object")
    return problems


# -- results.json --------------------------------------------------------------

def results_json_text(results: dict) -> str:
    """results.json's text: strict JSON (non-finite floats tagged), 2-space indent, trailing newline."""
    return json.dumps(json_values.enc_tree(results), indent=2, allow_nan=False, ensure_ascii=False) + "\n"


def write_results_json(results: dict, path: str | os.PathLike) -> Path:
    """Write ``results`` to ``path`` atomically as strict JSON; returns the path."""
    path = Path(path)
    write_text(path, results_json_text(results))
    return path


def _reject_constant(name: str):
    raise ValueError(f"non-standard JSON constant {name}")


def read_results(path: str | os.PathLike) -> dict:
    """Read results.json back (tagged floats kept; see :func:`number`).

    ``path`` may be the file or the folder holding ``results.json``.

    Raises:
        InputError: the file is missing or unreadable, not strict JSON, has
            another schema tag, or lacks the structure the report needs
            (every problem listed, one per line).
    """
    p = Path(path)
    if p.is_dir():
        p = p / RESULTS_JSON
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("results file not found", p) from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read results file: {e}", p) from None
    try:
        doc = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})", p) from None
    except ValueError as e:
        raise InputError(f"not strict JSON: {e}", p) from None
    problems = check_results(doc)
    if problems:
        raise InputError("not a usable r360gpu results file:\n" + "\n".join(f"  {q}" for q in problems), p)
    return doc


# -- results.csv ---------------------------------------------------------------

def _first_seen(items) -> list[str]:
    out: list[str] = []
    for x in items:
        if x not in out:
            out.append(x)
    return out


def _cell(value) -> str:
    """CSV text of one value: "" for None, true/false, ``repr`` for floats (exact; "inf", "-inf", "nan")."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        value = number(value)
        if value is None:
            return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


#: The ``kind`` of a results.csv row: a capture view, an orbit pose (``--orbit``), a pruned what-if
#: (``--prune-residuals``, method ``M+pruned`` at the capture views).
KINDS = ("capture", "orbit", "pruned")


def _records(results: dict):
    """(scene, method, kind, view record dict) in display order: per scene, the capture's rows, the
    orbit's (scenes.S.orbit) and the pruned what-ifs' (scenes.S.pruned)."""
    for s in scene_names(results):
        scene = results["scenes"][s]
        for m in method_names(results):
            entry = method_entry(results, s, m)
            for rec in (entry or {}).get("views") or []:
                yield s, m, KINDS[0], rec
        orbit = (scene.get("orbit") or {}).get("methods") or {}
        for m, entry in orbit.items():
            for rec in entry.get("views") or []:
                yield s, m, KINDS[1], rec
        for m, entry in (scene.get("pruned") or {}).items():
            for rec in entry.get("views") or []:
                yield s, m, KINDS[2], rec


def results_csv_rows(results: dict) -> tuple[list[str], list[list[str]]]:
    """The header and rows of results.csv: one row per (scene, method, view).

    Columns, in order:

    * ``scene, method, view``, then ``kind`` (`KINDS`: "capture", "orbit" or "pruned") when
      the run has orbit or pruned rows (``--orbit``, ``--prune-residuals``; without it every row is
      a capture view's);
    * ``empty_target``: the target mask of the view is empty (from any reading);
    * per semantic probe P (in order of first appearance): ``iou_pre:P``,
      ``iou_post:P``, ``iou_drop:P`` and ``detected@XI:P`` for every stored
      threshold (IoU_post >= XI; "true"/"false");
    * ``structural_mode``, then per structural probe P: ``sim_sam:P``,
      ``s_str:P`` (oriented score), ``n_a:P``, ``n_b:P`` (retained masks);
    * geometric: ``acc_depth`` (empty when excluded), ``geo_excluded``,
      ``threshold`` (xi_depth; depth units, or the 8-bit level in compat
      mode), ``geo_mode``, ``n_mask``, ``n_changed_in_mask``, ``n_no_depth_in_mask`` (pixels of
      the target with no depth after removal: a see-through hole);
    * fidelity against I_ref: ``psnr`` (dB; "inf" when identical), ``ssim``,
      ``lpips`` (empty when not computed), ``mse``.

    Missing values are empty cells; floats are written with ``repr``, so they
    read back exactly.
    """
    recs = list(_records(results))
    kinds = any(k != KINDS[0] for _, _, k, _ in recs)
    sem_probes = _first_seen(p for _, _, _, r in recs for p in (r.get("semantic") or {}))
    str_probes = _first_seen(p for _, _, _, r in recs for p in (r.get("structural") or {}))
    xis = sorted(
        {k for _, _, _, r in recs for sv in (r.get("semantic") or {}).values() for k in (sv.get("detected") or {})},
        key=float,
    )
    header = ["scene", "method", "view", *(["kind"] if kinds else []), "empty_target"]
    for p in sem_probes:
        header += [f"iou_pre:{p}", f"iou_post:{p}", f"iou_drop:{p}"] + [f"detected@{x}:{p}" for x in xis]
    header.append("structural_mode")
    for p in str_probes:
        header += [f"sim_sam:{p}", f"s_str:{p}", f"n_a:{p}", f"n_b:{p}"]
    header += ["acc_depth", "geo_excluded", "threshold", "geo_mode", "n_mask", "n_changed_in_mask",
               "n_no_depth_in_mask", "psnr", "ssim", "lpips", "mse"]

    rows = []
    for scene, method, kind, r in recs:
        sem = r.get("semantic") or {}
        st = r.get("structural") or {}
        geo = r.get("geometric") or {}
        fid = r.get("fidelity") or {}
        empties = [v.get("empty_target") for v in list(sem.values()) + list(st.values())]
        if geo:
            empties.append(geo.get("n_mask") == 0)
        empty = any(bool(e) for e in empties) if empties else None
        row = [scene, method, r.get("view", ""), *([kind] if kinds else []), _cell(empty)]
        for p in sem_probes:
            v = sem.get(p) or {}
            drop = v.get("iou_drop")
            if drop is None and v.get("iou_pre") is not None and v.get("iou_post") is not None:
                drop = float(v["iou_pre"]) - float(v["iou_post"])
            det = v.get("detected") or {}
            row += [_cell(v.get("iou_pre")), _cell(v.get("iou_post")), _cell(drop)]
            row += [_cell(det.get(x)) for x in xis]
        modes = _first_seen(v.get("mode") for v in st.values() if v.get("mode"))
        row.append(modes[0] if len(modes) == 1 else "/".join(modes))
        for p in str_probes:
            v = st.get(p) or {}
            row += [_cell(v.get("sim_sam")), _cell(v.get("s_str")), _cell(v.get("n_a")), _cell(v.get("n_b"))]
        row += [_cell(geo.get("acc_depth")), _cell(geo.get("excluded")), _cell(geo.get("threshold")),
                _cell(geo.get("mode")), _cell(geo.get("n_mask")), _cell(geo.get("n_changed_in_mask")),
                _cell(geo.get("n_no_depth_in_mask"))]
        row += [_cell(fid.get("psnr")), _cell(fid.get("ssim")), _cell(fid.get("lpips")), _cell(fid.get("mse"))]
        rows.append(row)
    return header, rows


def write_results_csv(results: dict, path: str | os.PathLike) -> Path:
    """Write results.csv (see :func:`results_csv_rows`) atomically; returns the path."""
    header, rows = results_csv_rows(results)
    buf = io.StringIO(newline="")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows(rows)
    path = Path(path)
    write_bytes(path, buf.getvalue().encode("utf-8"))
    return path


def write_results(results: dict, out_dir: str | os.PathLike) -> tuple[Path, Path]:
    """Write ``OUT/results.json`` and ``OUT/results.csv``; returns both paths."""
    out = Path(out_dir)
    return write_results_json(results, out / RESULTS_JSON), write_results_csv(results, out / RESULTS_CSV)
