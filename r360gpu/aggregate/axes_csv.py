"""Read a per-(scene, method) axes table from CSV into :class:`AxisCells`.

Format (UTF-8, comma separated, one header line)::

    # lines starting with '#' and blank lines are ignored
    scene,method,s_sem,s_geo,s_str[,n_views][,iou_drop]
    Sofa,GC,0.483,0.620,0.170
    ...

* ``s_sem``, ``s_geo``, ``s_str``: finite numbers in [0, 1].
* ``n_views`` (optional column): a positive integer in every row; enables
  view-weighted pooling over scenes.
* ``iou_drop`` (optional column): a finite number in [-1, 1] in every row.
* Other columns are ignored.  Each (scene, method) appears once, and every
  method has a row for every scene.  Scenes and methods keep the order of
  their first appearance.

Every problem raises :class:`~r360gpu.errors.InputError` naming the file and
the line/column.
"""
from __future__ import annotations

import csv
import math
import os

import numpy as np

from ..errors import InputError
from .cells import AXES, AxisCells

REQUIRED_COLUMNS: tuple[str, ...] = ("scene", "method", *AXES)
OPTIONAL_COLUMNS: tuple[str, ...] = ("n_views", "iou_drop")


def _number(text: str, where: str, path, lo: float, hi: float) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{where}: {text!r} is not a number", path) from None
    if not math.isfinite(value):
        raise InputError(f"{where}: {text!r} is not a finite number", path)
    if not lo <= value <= hi:
        raise InputError(f"{where}: {text} is outside [{lo:g}, {hi:g}]", path)
    return value


def _count(text: str, where: str, path) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 1 and value == int(value)):
        raise InputError(f"{where}: {text!r} is not a positive integer view count", path)
    return value


def read_axes_csv(path: str | os.PathLike) -> AxisCells:
    """Load the axes table at ``path``.

    Returns:
        :class:`AxisCells` with S scenes x M methods; ``n_views`` / ``iou_drop``
        are set when the file has those columns.

    Raises:
        InputError: unreadable file, missing or duplicated columns, a
            malformed or out-of-range value (naming line and column), a
            duplicate (scene, method), or methods that do not cover the same
            scenes.
    """
    try:
        with open(path, encoding="utf-8-sig", newline="") as f:
            text = f.read()
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start})", path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a CSV file", path) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", path) from None

    lines = [(no, line) for no, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError("empty CSV: no header line", path)

    def fields(line: str) -> list[str]:
        return [x.strip() for x in next(csv.reader([line]))]

    header_no, header_line = lines[0]
    header = fields(header_line)
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise InputError(f"line {header_no}: column {name!r} appears twice", path)
        seen.add(name)
    missing = [c for c in REQUIRED_COLUMNS if c not in seen]
    if missing:
        raise InputError(
            f"line {header_no}: missing column(s) {', '.join(missing)} (header has: {', '.join(header)})", path)
    col = {name: i for i, name in enumerate(header)}
    optional = [c for c in OPTIONAL_COLUMNS if c in col]
    if len(lines) == 1:
        raise InputError("no data rows after the header", path)

    cells: dict[tuple[str, str], dict[str, float]] = {}
    first_line: dict[tuple[str, str], int] = {}
    scenes: list[str] = []
    methods: list[str] = []
    for no, line in lines[1:]:
        row = fields(line)
        if len(row) != len(header):
            raise InputError(f"line {no}: expected {len(header)} fields, got {len(row)}", path)
        scene, method = row[col["scene"]], row[col["method"]]
        for name, value in (("scene", scene), ("method", method)):
            if not value:
                raise InputError(f"line {no}, column {name}: empty name", path)
        key = (scene, method)
        if key in cells:
            raise InputError(
                f"line {no}: duplicate row for (scene, method) = ({scene}, {method}); first on line {first_line[key]}",
                path)
        values = {name: _number(row[col[name]], f"line {no}, column {name}", path, 0.0, 1.0) for name in AXES}
        if "n_views" in col:
            values["n_views"] = _count(row[col["n_views"]], f"line {no}, column n_views", path)
        if "iou_drop" in col:
            values["iou_drop"] = _number(row[col["iou_drop"]], f"line {no}, column iou_drop", path, -1.0, 1.0)
        cells[key] = values
        first_line[key] = no
        if scene not in scenes:
            scenes.append(scene)
        if method not in methods:
            methods.append(method)

    for method in methods:
        lacking = [s for s in scenes if (s, method) not in cells]
        if lacking:
            raise InputError(
                f"method {method!r} has no row for scene(s) {', '.join(repr(s) for s in lacking)}; "
                "every method must cover the same scenes", path)

    def grid(name: str) -> np.ndarray:
        return np.array([[cells[(s, m)][name] for m in methods] for s in scenes], dtype=np.float64)

    return AxisCells(
        scenes=tuple(scenes),
        methods=tuple(methods),
        s_sem=grid("s_sem"),
        s_geo=grid("s_geo"),
        s_str=grid("s_str"),
        n_views=grid("n_views") if "n_views" in optional else None,
        iou_drop=grid("iou_drop") if "iou_drop" in optional else None,
    )
