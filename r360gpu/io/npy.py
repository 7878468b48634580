"""Reading a ``.npy`` array with its header checked before numpy allocates what it claims.

A few bytes of header can claim gigabytes (numpy allocates the claimed shape, and the header's own
length field, before reading a value); pickled objects are never unpickled.  Depth arrays
(:mod:`.renders`) and ``[target]`` indices (:mod:`r360gpu.lift.target`) are read here.
"""
from __future__ import annotations

import io
import os
import tokenize

import numpy as np

from ..errors import InputError
from ..util.filehash import read_file
from .paths import read_error

# What numpy's .npy header parser raises on a damaged header (it evaluates the header as a literal).
_NPY_HEADER_ERRORS = (ValueError, SyntaxError, TypeError, EOFError, OverflowError, tokenize.TokenError)


def npy_header(f, path) -> tuple[tuple[int, ...], np.dtype]:
    """(shape, dtype) from a .npy header, its length checked against the file before numpy reads it
    (numpy allocates what the length field claims)."""
    try:
        start = f.tell()
        size = f.seek(0, os.SEEK_END)
        f.seek(start)
        version = np.lib.format.read_magic(f)
        if version not in ((1, 0), (2, 0), (3, 0)):
            raise ValueError(f"unknown .npy format version {version}")
        field = f.read(2 if version == (1, 0) else 4)
        length = int.from_bytes(field, "little")
        if len(field) < (2 if version == (1, 0) else 4) or length > size - f.tell():
            raise ValueError(f"the header claims {length} bytes, the file has {size - f.tell()} left")
        f.seek(f.tell() - len(field))
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
    except _NPY_HEADER_ERRORS as e:
        raise InputError(f"not a valid .npy file ({type(e).__name__}: {str(e)[:200]})", path) from None
    return tuple(shape), dtype


def read_npy(path, *, max_values: int | None = None) -> np.ndarray:
    """The array of a .npy file (hashed as read), its header checked before numpy allocates what it
    claims: a shape the file's bytes (or ``max_values``) cannot hold, a damaged file, pickled objects
    (never unpickled) or an .npz archive are an InputError naming the file."""
    try:
        data = read_file(path)  # hashed as read (util.filehash)
    except OSError as e:
        raise read_error(e, path) from None
    if data[:4] == b"PK\x03\x04":
        raise InputError("an .npz archive, not one .npy array (save the array with np.save)", path)
    f = io.BytesIO(data)
    shape, dtype = npy_header(f, path)
    n = int(np.prod(shape, dtype=object)) if shape else 1
    too_many = max_values is not None and n > max_values
    if too_many or (not dtype.hasobject and n * dtype.itemsize > len(data) - f.tell()):
        raise InputError(f"the .npy header claims shape {shape} of {dtype}, more than the file's "
                         f"{len(data)} bytes hold (truncated?) or r360gpu decodes", path)
    try:
        arr = np.load(io.BytesIO(data), allow_pickle=False)
    except _NPY_HEADER_ERRORS as e:
        raise InputError(f"not a valid .npy file ({type(e).__name__}: {str(e)[:200]})", path) from None
    if not isinstance(arr, np.ndarray):
        raise InputError("not a .npy array file", path)
    return arr
