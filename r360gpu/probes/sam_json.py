"""Fast reading of SAM JSON files whose masks are nested 0/1 lists.

The public scripts write each mask as ``bool_mask.tolist()`` through
``json.dump``: a ~1000 x 1200 mask is 1.2 million ``true``/``false`` tokens,
and ``json.loads`` + ``np.array`` spend ~0.1 s per mask building and
converting Python lists.  :func:`load` cuts every ``"segmentation"`` /
``"mask"`` nested list out of the raw bytes, decodes it with byte-level
numpy operations, and parses only the remaining (small) JSON with the
standard library; the masks come back as bool (H, W) arrays in place of the
lists.

A nested list is decoded here only when its text is exactly what
``json.dump`` writes for a rectangular list of ``true``/``false`` or 0/1
values (", " or "," separators; see :func:`parse_bool_grid`, the path for
``bool_mask.tolist()``, and :func:`parse_grid`, any 0/1/true/false mix); for
such text ``np.array(list) != 0`` gives the same mask.  Any other file (ragged rows,
empty lists, floats such as ``1.0``, indented files, malformed JSON, ...) is
read the standard way, so results and error messages are exactly those of
:func:`r360gpu.probes.precomputed.read_sam_records`
(tests/test_probes_sam_json.py).
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from ..errors import InputError

_KEY = re.compile(rb'"(?:segmentation|mask)"\s*:\s*\[')
_PLACEHOLDER = "\x00r360gpu-mask:"


def _u64(b: bytes) -> int:
    return int.from_bytes(b[:8].ljust(8, b"\0"), "little")


def _mask(n: int) -> int:
    return (1 << 8 * min(n, 8)) - 1


def parse_grid(text: bytes) -> np.ndarray | None:
    """bool (H, W) from the text of a nested 0/1 (or true/false) list written
    as ``json.dump`` writes it (", " or "," separators, no other whitespace),
    or None for any other text.

    Every value token starts with "t", "f", "0" or "1", and no other byte of
    such text does.  Each token is checked, with what follows it up to the
    next token, as one unaligned 8-byte word ("true, ", "false], [", ...), and
    the pieces must tile the text exactly, so the text is proven to be the
    rendering of the decoded mask.
    """
    a = np.frombuffer(text, np.uint8)
    if a.size < 5 or text[:2] != b"[[" or text[-2:] != b"]]":
        return None
    starts = np.flatnonzero((a == _T) | (a == _F) | (a == _ONE) | (a == _ZERO))
    n = starts.size
    first_close = text.find(b"]")
    if n == 0 or starts[0] != 2:
        return None
    w = int(np.searchsorted(starts, first_close))
    if w == 0 or n % w:
        return None
    comma = text.find(b",")
    sep = b", " if comma < 0 or text[comma + 1 : comma + 2] == b" " else b","
    cls = _CLASS[a[starts]]  # 0: "0", 1: "1", 2: "f", 3: "t"
    k = cls * np.uint8(3)  # + kind: 0 inside a row, 1 last of a row, 2 last of all
    k[w - 1 :: w] += np.uint8(1)
    k[-1] += np.uint8(1)
    want, wmask, length = _patterns(sep)
    # Unaligned 8-byte reads at every token (the text is padded by 8 bytes).
    buf = np.concatenate([a, np.zeros(16, np.uint8)])
    words = np.ndarray((a.size + 8,), "<u8", buf, strides=(1,))[starts]
    words ^= want[k]
    words &= wmask[k]
    if words.any():
        return None
    lens = length[k]
    # Pieces longer than 8 bytes ("false], [") have their 9th byte checked too.
    long = np.flatnonzero(lens > 8)
    if long.size and not (buf[starts[long] + 8] == ord("[")).all():
        return None
    # The pieces tile the text: each ends where the next token starts.
    if starts[-1] + lens[-1] != a.size or not (np.diff(starts) == lens[:-1]).all():
        return None
    return (cls & 1).astype(bool).reshape(n // w, w)


def parse_bool_grid(raw: bytes, lo: int, hi: int) -> np.ndarray | None:
    """bool (H, W) from ``raw[lo:hi]`` when that is exactly the ``json.dump``
    text of a rectangular list of ``true``/``false`` (", " or "," separators),
    else None.  No copy of the text is made.

    The fast path for what SAM scripts write (``bool_mask.tolist()``), faster
    than :func:`parse_grid` (23 vs 29 ms per 1000 x 1200 mask, file reading
    included, in bench/bench_sam_json.py): every
    token ends in the only "e" bytes such text has, so one byte comparison
    finds them all, and the byte before each tells "true" from "false".  The
    proof that the text is the rendering of the decoded mask: the text starts
    with "[[" and ends with "]]"; each token's first 4 bytes are "true" or
    "fals" (its "e" was found); the gaps between tokens have the lengths of
    ``sep`` (inside a row) or "]" + sep + "[" (between rows, at every W-th
    token) and those bytes -- so every byte of the text is checked once.
    """
    n_bytes = hi - lo
    if n_bytes < 8 or raw[lo : lo + 2] != b"[[" or raw[hi - 2 : hi] != b"]]":
        return None
    text = np.frombuffer(raw, np.uint8, n_bytes, lo)
    e = np.flatnonzero(text == _E)
    n = e.size
    first_close = raw.find(b"]", lo, hi) - lo
    w = int(np.searchsorted(e, first_close))
    if n == 0 or w == 0 or n % w or e[w - 1] + 1 != first_close:
        return None
    after = raw[lo + e[0] + 1 : lo + e[0] + 4]  # the first gap: inside a row, or between rows when W is 1
    sep = b", " if (after[:2] == b", " if w > 1 else after == b"], ") else b","
    is_false = text[e - 1] == _S
    starts = e - 3
    starts -= is_false
    if starts[0] != 2 or e[-1] + 3 != n_bytes:  # "[[" first, "]]" last
        return None
    words = np.ndarray((n_bytes - 3,), "<u4", raw, lo, (1,))[starts]  # unaligned 4-byte reads
    if not np.array_equal(words, np.where(is_false, _FALS, _TRUE)):
        return None
    # gap k (after token k): len(sep) bytes, or len(sep) + 2 after the last token of a row
    gap = starts[1:] - e[:-1]
    gap[w - 1 :: w] -= 2
    if not (gap == len(sep) + 1).all():
        return None
    first = text[e[:-1] + 1]  # "," inside a row, "]" after its last token
    first[w - 1 :: w] ^= np.uint8(ord("]") ^ ord(","))
    if not (first == ord(",")).all():
        return None
    if len(sep) == 2:
        second = text[e[:-1] + 2]
        second[w - 1 :: w] = ord(" ")  # checked with the whole row gap below
        if not (second == ord(" ")).all():
            return None
    row_gap = np.frombuffer(b"]" + sep + b"[", np.uint8)
    row_ends = e[w - 1 : -1 : w]
    if row_ends.size and not (text[row_ends[:, None] + np.arange(1, row_gap.size + 1)] == row_gap).all():
        return None
    return np.logical_not(is_false).reshape(n // w, w)


_E, _S = ord("e"), ord("s")
_TRUE, _FALS = np.uint32(_u64(b"true")), np.uint32(_u64(b"fals"))
_T, _F, _ONE, _ZERO = ord("t"), ord("f"), ord("1"), ord("0")
_CLASS = np.zeros(256, np.uint8)
_CLASS[[_ZERO, _ONE, _F, _T]] = [0, 1, 2, 3]
_PATTERNS: dict[bytes, tuple] = {}


def _patterns(sep: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(word, mask, length) per class * 3 + kind of what follows a token."""
    if sep not in _PATTERNS:
        words, masks, lengths = [], [], []
        for tok in (b"0", b"1", b"false", b"true"):
            for tail in (sep, b"]" + sep + b"[", b"]]"):
                piece = tok + tail
                words.append(_u64(piece))
                masks.append(_mask(len(piece)))
                lengths.append(len(piece))
        _PATTERNS[sep] = (np.array(words, np.uint64), np.array(masks, np.uint64), np.array(lengths, np.int64))
    return _PATTERNS[sep]


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


def _grid_end(raw: bytes, start: int) -> int:
    """End of the first "]]" after ``start`` (where json.dump ends a grid), or -1.

    One memchr-speed search per row: ``bytes.find(b"]]")`` is several times
    slower on megabytes of true/false text."""
    i = raw.find(b"]", start)
    while i >= 0 and raw[i + 1 : i + 2] != b"]":
        i = raw.find(b"]", i + 2)
    return -1 if i < 0 else i + 2


def _fast(raw: bytes):
    """The parsed JSON with nested-list masks as arrays, or None to fall back."""
    masks: list[np.ndarray] = []
    pieces: list[bytes] = []
    pos = 0
    for m in _KEY.finditer(raw):
        start = m.end() - 1
        if start < pos:
            return None
        end = _grid_end(raw, start)
        if end < 0:
            return None
        grid = parse_bool_grid(raw, start, end)
        if grid is None:
            grid = parse_grid(raw[start:end])
        if grid is None:
            return None
        pieces += [raw[pos:start], json.dumps(f"{_PLACEHOLDER}{len(masks)}").encode()]
        masks.append(grid)
        pos = end
    pieces.append(raw[pos:])
    used = set()

    def hook(obj: dict):
        for k, v in obj.items():
            if isinstance(v, str) and v.startswith(_PLACEHOLDER):
                i = int(v[len(_PLACEHOLDER) :])
                if i in used or i >= len(masks):
                    raise ValueError("mask marker seen twice")
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
