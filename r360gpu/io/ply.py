"""Minimal PLY container reader/writer (header + elements as numpy structured arrays).

Handles the three PLY encodings (``ascii``, ``binary_little_endian``,
``binary_big_endian``) and all scalar property types of the PLY spec.  List
properties (e.g. a mesh's ``face`` element) are parsed only to be skipped:
elements that have one are not returned.  Format-specific meaning (3DGS,
compressed splats) lives in the modules that use this one.

Every structural problem (not a PLY file, malformed header, truncated data,
more data than the header declares) is an InputError naming the file.
"""
from __future__ import annotations

import io
import os
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import InputError
from ..util.filehash import read_file
from .paths import read_error
from ..util.atomic import atomic_open

# PLY scalar type names (both the classic and the sized spellings) -> numpy type code.
_PLY_TYPES = {
    "char": "i1", "int8": "i1",
    "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4",
    "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4",
    "double": "f8", "float64": "f8",
}
# numpy type code -> PLY type name written by write_ply.
_NUMPY_TO_PLY = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort",
                 "i4": "int", "u4": "uint", "f4": "float", "f8": "double"}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
# A header longer than this is not a PLY header (guards against scanning a huge non-PLY file).
_MAX_HEADER_BYTES = 1 << 20


@dataclass(frozen=True)
class PlyProperty:
    """One property: ``code`` is a numpy type code ('f4', 'u1', ...); lists also have ``count_code``."""

    name: str
    code: str
    count_code: str | None = None

    @property
    def is_list(self) -> bool:
        return self.count_code is not None


@dataclass(frozen=True)
class PlyElement:
    name: str
    count: int
    properties: tuple[PlyProperty, ...]

    @property
    def has_lists(self) -> bool:
        return any(p.is_list for p in self.properties)

    def dtype(self, endian: str = "<") -> np.dtype:
        """Packed structured dtype of one record (only for elements without lists)."""
        return np.dtype([(p.name, endian + p.code) for p in self.properties])

    def property_names(self) -> list[str]:
        return [p.name for p in self.properties]


@dataclass
class PlyData:
    """A parsed PLY file: ``format``, ``elements`` (header order), ``comments`` and
    ``arrays``: element name -> structured array (native byte order) for every
    element without list properties."""

    path: str
    format: str
    elements: list[PlyElement]
    comments: list[str] = field(default_factory=list)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def element(self, name: str) -> PlyElement | None:
        for e in self.elements:
            if e.name == name:
                return e
        return None


def _parse_header(data: bytes, path: str) -> tuple[str, list[PlyElement], list[str], int]:
    if not (data.startswith(b"ply\n") or data.startswith(b"ply\r\n")):
        raise InputError("not a PLY file (it does not start with 'ply')", path)
    pos = 0
    fmt = None
    elements: list[PlyElement] = []
    current: tuple[str, int, list[PlyProperty]] | None = None
    comments: list[str] = []
    first = True
    while True:
        nl = data.find(b"\n", pos, _MAX_HEADER_BYTES)
        if nl < 0:
            raise InputError("PLY header has no 'end_header' line (file truncated or not a PLY file)", path)
        raw = data[pos:nl].rstrip(b"\r")
        pos = nl + 1
        try:
            line = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise InputError("PLY header contains non-ASCII bytes", path) from None
        if first:
            first = False
            continue  # the 'ply' magic line
        words = line.split()
        if not words:
            continue
        key = words[0]
        if key in ("comment", "obj_info"):
            comments.append(line[len(key):].strip())
        elif key == "format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise InputError(f"unsupported PLY format line {line!r}", path)
            fmt = words[1]
        elif key == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise InputError(f"malformed PLY element line {line!r}", path)
            if current is not None:
                elements.append(PlyElement(current[0], current[1], tuple(current[2])))
            if any(e.name == words[1] for e in elements):
                raise InputError(f"PLY element {words[1]!r} is declared twice", path)
            current = (words[1], int(words[2]), [])
        elif key == "property":
            if current is None:
                raise InputError(f"PLY property before any element: {line!r}", path)
            if len(words) == 5 and words[1] == "list":
                if words[2] not in _PLY_TYPES or words[3] not in _PLY_TYPES:
                    raise InputError(f"unknown PLY property type in {line!r}", path)
                prop = PlyProperty(words[4], _PLY_TYPES[words[3]], _PLY_TYPES[words[2]])
            elif len(words) == 3:
                if words[1] not in _PLY_TYPES:
                    raise InputError(f"unknown PLY property type {words[1]!r} in {line!r}", path)
                prop = PlyProperty(words[2], _PLY_TYPES[words[1]])
            else:
                raise InputError(f"malformed PLY property line {line!r}", path)
            if any(p.name == prop.name for p in current[2]):
                raise InputError(f"PLY element {current[0]!r} declares property {prop.name!r} twice", path)
            current[2].append(prop)
        elif key == "end_header":
            break
        else:
            raise InputError(f"unexpected PLY header line {line!r}", path)
    if current is not None:
        elements.append(PlyElement(current[0], current[1], tuple(current[2])))
    if fmt is None:
        raise InputError("PLY header has no 'format' line", path)
    return fmt, elements, comments, pos


def read_ply_header(path: str | os.PathLike) -> PlyData:
    """Only the header of a PLY file (``arrays`` left empty); cheap, for sniffing formats."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            head = f.read(_MAX_HEADER_BYTES)
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", path) from None
    fmt, elements, comments, _ = _parse_header(head, path)
    return PlyData(path, fmt, elements, comments)


def read_ply(path: str | os.PathLike) -> PlyData:
    """Parse a whole PLY file; see :class:`PlyData`."""
    path = os.fspath(path)
    try:
        data = read_file(path)  # hashed as read (util.filehash): the cache key is what was decoded
    except OSError as e:
        raise read_error(e, path) from None
    fmt, elements, comments, offset = _parse_header(data, path)
    ply = PlyData(path, fmt, elements, comments)
    if fmt == "ascii":
        _read_ascii(data, offset, ply)
    else:
        _read_binary(data, offset, _FORMATS[fmt], ply)
    return ply


def _read_binary(data: bytes, offset: int, endian: str, ply: PlyData) -> None:
    for el in ply.elements:
        if el.has_lists:
            offset = _skip_binary_lists(data, offset, endian, el, ply.path)
            continue
        if not el.properties:
            continue  # an element without properties holds no bytes
        dt = el.dtype(endian)
        need = dt.itemsize * el.count
        if offset + need > len(data):
            have = max(0, (len(data) - offset) // max(dt.itemsize, 1))
            raise InputError(
                f"truncated: element {el.name!r} declares {el.count} records but the file holds "
                f"only {have}", ply.path)
        arr = np.frombuffer(data, dtype=dt, count=el.count, offset=offset)
        # Native byte order: keep the zero-copy (read-only) view of the file's bytes.
        ply.arrays[el.name] = arr if arr.dtype.isnative else arr.astype(el.dtype("="))
        offset += need
    if offset != len(data):
        raise InputError(
            f"{len(data) - offset} bytes after the data the PLY header declares "
            f"(wrong element count in the header?)", ply.path)


def _skip_binary_lists(data: bytes, offset: int, endian: str, el: PlyElement, path: str) -> int:
    # Records with lists have variable size: walk them one by one (only mesh-like elements do this).
    for _ in range(el.count):
        for p in el.properties:
            if p.is_list:
                cdt = np.dtype(endian + p.count_code)
                if offset + cdt.itemsize > len(data):
                    raise InputError(f"truncated inside element {el.name!r}", path)
                n = int(np.frombuffer(data, cdt, 1, offset)[0])
                offset += cdt.itemsize + n * np.dtype(p.code).itemsize
            else:
                offset += np.dtype(p.code).itemsize
            if offset > len(data):
                raise InputError(f"truncated inside element {el.name!r}", path)
    return offset


def _read_ascii(data: bytes, offset: int, ply: PlyData) -> None:
    try:
        tokens = data[offset:].decode("ascii").split()
    except UnicodeDecodeError:
        raise InputError("ASCII PLY data contains non-ASCII bytes", ply.path) from None
    pos = 0
    for el in ply.elements:
        if el.has_lists:
            for _ in range(el.count):
                for p in el.properties:
                    if pos >= len(tokens):
                        raise InputError(f"truncated: element {el.name!r} ends early", ply.path)
                    if p.is_list:
                        try:
                            pos += int(tokens[pos]) + 1
                        except ValueError:
                            raise InputError(f"bad list length {tokens[pos]!r} in element {el.name!r}",
                                             ply.path) from None
                    else:
                        pos += 1
            continue
        if not el.properties:
            continue
        nprop = len(el.properties)
        need = nprop * el.count
        if pos + need > len(tokens):
            have = (len(tokens) - pos) // max(nprop, 1)
            raise InputError(
                f"truncated: element {el.name!r} declares {el.count} records but the file holds "
                f"only {have}", ply.path)
        try:
            values = np.array(tokens[pos:pos + need], dtype=np.float64).reshape(el.count, nprop)
        except ValueError:
            raise InputError(f"non-numeric value in element {el.name!r}", ply.path) from None
        pos += need
        arr = np.empty(el.count, dtype=el.dtype("="))
        for j, p in enumerate(el.properties):
            arr[p.name] = values[:, j]
        ply.arrays[el.name] = arr
    if pos > len(tokens):
        raise InputError("truncated: the last element ends early", ply.path)
    if pos != len(tokens):
        raise InputError(
            f"{len(tokens) - pos} values after the data the PLY header declares "
            f"(wrong element count in the header?)", ply.path)


def write_ply(path: str | os.PathLike, elements: Sequence[tuple[str, np.ndarray]],
              comments: Sequence[str] = (), format: str = "binary_little_endian") -> None:
    """Write structured arrays as PLY elements (atomically).

    elements: (name, structured array) in file order; field types must be
    among int8/16/32, uint8/16/32, float32/64.  format: 'ascii',
    'binary_little_endian' or 'binary_big_endian'.
    """
    if format not in _FORMATS:
        raise ValueError(f"unknown PLY format {format!r}")
    lines = ["ply", f"format {format} 1.0"] + [f"comment {c}" for c in comments]
    for name, arr in elements:
        lines.append(f"element {name} {len(arr)}")
        for fname in arr.dtype.names:
            code = arr.dtype[fname].str[1:]
            if code not in _NUMPY_TO_PLY:
                raise ValueError(f"field {fname!r} has a type PLY cannot store ({arr.dtype[fname]})")
            lines.append(f"property {_NUMPY_TO_PLY[code]} {fname}")
    lines.append("end_header")
    with atomic_open(path, "wb") as f:
        f.write(("\n".join(lines) + "\n").encode("ascii"))
        for _, arr in elements:
            if format == "ascii":
                buf = io.StringIO()
                fmts = [("%.9g" if arr.dtype[n].kind == "f" and arr.dtype[n].itemsize == 4 else
                         "%.17g" if arr.dtype[n].kind == "f" else "%d") for n in arr.dtype.names]
                if len(arr):
                    np.savetxt(buf, arr, fmt=fmts)
                f.write(buf.getvalue().encode("ascii"))
            else:
                endian = _FORMATS[format]
                out_dt = np.dtype([(n, endian + arr.dtype[n].str[1:]) for n in arr.dtype.names])
                f.write(arr.astype(out_dt).tobytes())
