"""Fast reading of SAM JSON files whose masks are nested 0/1 lists.

The public scripts write each mask as ``bool_mask.tolist()`` through
``json.dump``: a ~1000 x 1200 mask is 1.2 million ``true``/``false`` tokens,
and ``json.loads`` + ``np.array`` spend ~0.1 s per mask building and
converting Python lists.  :func:`load` cuts every ``"segmentation"`` /
``"mask"`` nested list out of the raw bytes, decodes it with byte-level
numpy operations, and parses only the remaining (small) JSON with the
standard library; the masks come back as bool (H, W) arrays in place of the
lists.

A nested list is decoded here only when its text, with whitespace removed
and ``true``/``false`` written as ``1``/``0``, is exactly
``[[v,v,...,v],...,[v,...,v]]`` with every ``v`` in {0, 1} and every row of
one length; for such text ``np.array(list) != 0`` gives the same mask.  Any
other file (ragged rows, empty lists, floats such as ``1.0``, malformed
JSON, ...) is read the standard way, so results and error messages are
exactly those of :func:`r360gpu.probes.precomputed.read_sam_records`
(tests/test_probes_sam_json.py).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from ..errors import InputError

_KEY = re.compile(rb'"(?:segmentation|mask)"\s*:\s*\[')
_END = re.compile(rb"\]\s*\]")
_PLACEHOLDER = "\x00r360gpu-mask:"
_LETTERS = b"rueals"
_SPACE = ord(" ")
_OPEN, _CLOSE, _COMMA = ord("["), ord("]"), ord(",")
_VALUE = np.full(256, 2, np.uint8)  # value byte -> 0/1, anything else -> 2
_VALUE[[ord("0"), ord("f")]] = 0
_VALUE[[ord("1"), ord("t")]] = 1


def parse_grid(text: bytes) -> np.ndarray | None:
    """bool (H, W) from the text of a nested 0/1 (or true/false) list, or None
    when the text is not exactly a rectangular list of such values.  Only the
    spellings of ``json.dump`` (", " or "," separators) are decoded here;
    other whitespace (e.g. indented files) gives None."""
    if b"\n" in text or b"\t" in text or b"\r" in text:
        return None
    dense = text.translate(None, b" ")
    if len(dense) != len(text):
        a = np.frombuffer(text, np.uint8)
        sp = a == _SPACE
        # Every space follows a comma, so no token is split by one.
        if sp[0] or (sp[1:] & (a[:-1] != _COMMA)).any():
            return None
    compact = dense.translate(None, _LETTERS)  # "true" -> "t", "false" -> "f"
    c = np.frombuffer(compact, np.uint8)
    first = compact.find(b"]")
    if len(compact) < 5 or first < 3 or (first - 1) % 2 or c[0] != _OPEN or c[-1] != _CLOSE:
        return None
    w = (first - 1) // 2
    row = 2 * w + 2  # "[v,v,...,v]" plus the "," that separates rows
    body = np.empty(len(c) - 1, np.uint8)
    body[:-1] = c[1:-1]
    body[-1] = _COMMA
    if body.size % row:
        return None
    grid = body.reshape(-1, row)
    vals = _VALUE[grid[:, 1 : 2 * w : 2]]
    if not (
        (grid[:, 0] == _OPEN).all()
        and (grid[:, 2 * w] == _CLOSE).all()
        and (grid[:, 2 * w + 1] == _COMMA).all()
        and (grid[:, 2 : 2 * w : 2] == _COMMA).all()
        and (vals <= 1).all()
    ):
        return None
    if not _spelled(c, np.frombuffer(dense, np.uint8)):
        return None
    return vals.view(bool)


_TRUE = int.from_bytes(b"true", "little")
_FALSE = int.from_bytes(b"false", "little")


def _spelled(c: np.ndarray, d: np.ndarray) -> bool:
    """Whether ``d`` (no spaces) is ``c`` with each "t" written "true" and each
    "f" written "false": every "t"/"f" of ``d`` starts that word (read as one
    unaligned integer at each byte) and no other letter of the words occurs."""
    n_t = int(np.count_nonzero(c == ord("t")))
    n_f = int(np.count_nonzero(c == ord("f")))
    if d.size - c.size != 3 * n_t + 4 * n_f:
        return False
    if d.size < 8:
        d = np.concatenate([d, np.zeros(8 - d.size, np.uint8)])
    # Every byte position read as an unaligned little-endian u64 (the last 7
    # positions cannot start a whole word; they are read from a padded copy).
    wide = np.ndarray((d.size - 7,), "<u8", d, strides=(1,))
    tail = np.ndarray((7,), "<u8", np.concatenate([d[-7:], np.zeros(7, np.uint8)]), strides=(1,))
    for letter, word, width, n in ((ord("t"), _TRUE, 4, n_t), (ord("f"), _FALSE, 5, n_f)):
        if not n:
            continue
        at = np.flatnonzero(d == letter)
        split = np.searchsorted(at, d.size - 7)
        words = np.concatenate([wide[at[:split]], tail[at[split:] - (d.size - 7)]])
        if not (words & np.uint64((1 << 8 * width) - 1) == np.uint64(word)).all():
            return False
    return True


def _read(path: Path) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror or exc})", path) from None


def _standard(raw: bytes, path: Path):
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise InputError(f"not utf-8 text ({exc.reason} at byte {exc.start})", path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"malformed JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})", path) from None


def _fast(raw: bytes):
    """The parsed JSON with nested-list masks as arrays, or None to fall back."""
    masks: list[np.ndarray] = []
    pieces: list[bytes] = []
    pos = 0
    for m in _KEY.finditer(raw):
        start = m.end() - 1
        if start < pos:
            return None
        end = _END.search(raw, start)
        if end is None:
            return None
        grid = parse_grid(raw[start : end.end()])
        if grid is None:
            return None
        pieces += [raw[pos:start], json.dumps(f"{_PLACEHOLDER}{len(masks)}").encode()]
        masks.append(grid)
        pos = end.end()
    pieces.append(raw[pos:])
    used = set()

    def hook(obj: dict):
        for k, v in obj.items():
            if isinstance(v, str) and v.startswith(_PLACEHOLDER):
                i = int(v[len(_PLACEHOLDER) :])
                if i in used or i >= len(masks):
                    raise ValueError("placeholder seen twice")
                used.add(i)
                obj[k] = masks[i]
        return obj

    try:
        data = json.loads(b"".join(pieces).decode("utf-8"), object_hook=hook)
    except (ValueError, UnicodeDecodeError):  # JSONDecodeError is a ValueError
        return None
    if len(used) != len(masks):
        return None
    return data


def load(path) -> object:
    """A SAM JSON file parsed, nested-list masks as bool (H, W) arrays (see the
    module docstring); InputError naming the file when it cannot be read."""
    path = Path(path)
    raw = _read(path)
    data = _fast(raw) if (b'"segmentation"' in raw or b'"mask"' in raw) else None
    return _standard(raw, path) if data is None else data
