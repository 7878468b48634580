"""Fast reading of SAM JSON files whose masks are nested 0/1 lists.

The public scripts write each mask as ``bool_mask.tolist()`` through
``json.dump``: a ~1000 x 1200 mask is 1.2 million ``true``/``false`` tokens,
and ``json.loads`` + ``np.array`` spend ~60 ms per mask building and
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
:func:`r360gpu.probes.sam_records.read_sam_records`
(tests/test_probes_sam_json.py).
"""
from __future__ import annotations

import json
import re
import threading
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


def parse_bool_grid(raw: bytes, lo: int, hi: int, closes: list[int] | None = None) -> np.ndarray | None:
    """bool (H, W) from ``raw[lo:hi]`` when that is exactly the ``json.dump``
    text of a rectangular list of ``true``/``false`` (", " or "," separators),
    else None.

    The fast path for what SAM scripts write (``bool_mask.tolist()``).  Masks
    of a few runs of ``true`` per row (what segmenters give) are decoded from
    those runs and checked by rendering (:func:`parse_bool_runs`); masks of
    many short runs go through the token-by-token check
    (:func:`parse_bool_tokens`), whose cost does not grow with the runs.
    Both give the same answer on every text (tests/test_probes_sam_json.py).
    closes: :func:`_closes` of the grid when the caller has it.
    """
    if raw[lo + 2 : lo + 3] not in (b"t", b"f"):  # 0/1 grids and non-grids: not this path's
        return None
    grid = parse_bool_runs(raw, lo, hi, max_runs=max(16, (hi - lo) // _BYTES_PER_RUN), closes=closes)
    return parse_bool_tokens(raw, lo, hi) if grid is None else grid


#: Above one ``true`` run per this many bytes of text, the run way (a Python
#: step per run) stops being the faster (bench/bench_sam_json.py, its runs table).
_BYTES_PER_RUN = 1024


def parse_bool_runs(raw: bytes, lo: int, hi: int, max_runs: int | None = None,
                    closes: list[int] | None = None) -> np.ndarray | None:
    """:func:`parse_bool_grid` by runs: None also when the text has more than
    ``max_runs`` runs of ``true``.  closes: :func:`_closes` ``(raw, lo, hi)``
    when the caller has it (it found the grid's end with them).

    Only "t" starts a ``true`` token and nothing else in such text has a "t",
    so a run of ``true`` inside a row is a series of "t" bytes one token
    apart, and the rows end at the "]" bytes: the positions of those bytes
    give every run's row, column and length (the ``false`` tokens between are
    counted from the byte gaps).  The mask
    is filled from the runs, rendered back to the text ``json.dump`` writes
    for it, and compared with ``raw[lo:hi]`` byte for byte, so a mask is
    returned only for the exact text of that mask.
    """
    n_bytes = hi - lo
    if n_bytes < 8 or raw[lo : lo + 2] != b"[[" or raw[hi - 2 : hi] != b"]]":
        return None
    comma = raw.find(b",", lo, hi)
    sep = b"," if comma >= 0 and raw[comma + 1 : comma + 2] != b" " else b", "
    q = 4 + len(sep)  # from one "true" token's "t" to the next one's in the same row
    text = np.frombuffer(raw, np.uint8, n_bytes, lo)
    at = np.flatnonzero(np.equal(text, _T, out=_scratch(n_bytes)))  # the first byte of every true token
    # a run's tokens are q bytes apart: it starts after a larger gap, and ends before one
    gap = np.diff(at) != q
    starts = at[np.concatenate(([True], gap))] if at.size else at
    if max_runs is not None and starts.size > max_runs:
        return None
    ends = at[np.concatenate((gap, [True]))] if at.size else at
    if closes is None:
        closes = _closes(raw, lo, hi)
    if not closes or closes[-1] != hi - 1:  # every "]": one per row, then the outer one, the text's last byte
        return None
    h = len(closes) - 1
    if h < 1 or starts.size != ends.size:
        return None
    row_at = np.empty(h, np.int64)  # where each row's first token starts:
    row_at[0] = 2  # after "[["
    row_at[1:] = np.asarray(closes[: h - 1], np.int64) + (2 + len(sep) - lo)  # after the row before's "]" + sep + "["
    length, rem = np.divmod(ends - starts, q)
    length += 1
    row = np.searchsorted(row_at, starts, "right") - 1
    if rem.any() or (row < 0).any():
        return None
    # tokens before each run in its row: the earlier runs' "true" tokens, and "false" tokens of q + 1 bytes
    before = np.cumsum(length) - length
    n_true = before - before[np.searchsorted(row, row)]
    n_false, rem = np.divmod(starts - row_at[row] - n_true * q, q + 1)
    col = n_true + n_false
    t0 = int(length[row == 0].sum())
    w, rem0 = divmod(closes[0] - lo - 2 + len(sep) - t0 * q, q + 1)
    w += t0
    # 4 bytes per token at the least: a text that cannot hold an (h, w) grid allocates nothing
    if rem.any() or rem0 or w < 1 or 4 * h * w > n_bytes or (n_false < 0).any() or (col + length > w).any():
        return None
    mask = np.zeros((h, w), bool)
    rows: list = [None] * h
    for r, c, n in zip(row.tolist(), col.tolist(), length.tolist()):
        mask[r, c : c + n] = True
        if rows[r] is None:
            rows[r] = []
        rows[r] += (c, n)
    # the text json.dump writes for the mask, compared row by row in place (no copy of the whole)
    fs, ts = b"false" + sep, b"true" + sep
    empty = b"[" + fs * (w - 1) + b"false]" + sep
    pos = lo + 1
    for r, runs in enumerate(rows):
        if runs is None:
            piece = empty
        else:
            parts, c = [b"["], 0
            for k in range(0, len(runs), 2):
                parts += [fs * (runs[k] - c), ts * runs[k + 1]]
                c = runs[k] + runs[k + 1]
            parts.append(fs * (w - c))
            piece = b"".join(parts)[: -len(sep)] + b"]" + sep
        if r == h - 1:
            piece = piece[: -len(sep)] + b"]"
        if not raw.startswith(piece, pos):
            return None
        pos += len(piece)
    return mask if pos == hi else None


_LOCAL = threading.local()


#: Largest grid text whose scratch buffer a thread keeps (a 1920 x 1080 mask is ~14 MB).
_SCRATCH_KEPT = 1 << 25


def _scratch(n: int) -> np.ndarray:
    """A bool buffer of ``n`` bytes, the calling thread's own: reused from grid to grid, so the
    megabyte-sized temporary is not allocated and faulted in for every mask."""
    if n > _SCRATCH_KEPT:
        return np.empty(n, bool)
    buf = getattr(_LOCAL, "buf", None)
    if buf is None or buf.size < n:
        buf = _LOCAL.buf = np.empty(n, bool)
    return buf[:n]


def parse_bool_tokens(raw: bytes, lo: int, hi: int) -> np.ndarray | None:
    """:func:`parse_bool_grid` token by token.  No copy of the text is made.

    Every
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


_E, _S, _CLOSE = ord("e"), ord("s"), ord("]")
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


def _closes(raw: bytes, start: int, stop: int) -> list[int] | None:
    """Positions of every "]" in ``raw[start:stop]`` up to the first "]]" (both of its brackets,
    where json.dump ends a grid), or None when there is no "]]".

    One memchr-speed search per row: ``bytes.find(b"]]")`` is several times
    slower on megabytes of true/false text.  The row ends found on the way
    are the rows :func:`parse_bool_runs` needs."""
    out = []
    i = raw.find(b"]", start, stop)
    while i >= 0:
        out.append(i)
        if i + 1 < stop and raw[i + 1] == _CLOSE:
            out.append(i + 1)
            return out
        i = raw.find(b"]", i + 2, stop)
    return None


def _grid_end(raw: bytes, start: int, stop: int | None = None) -> int:
    """End of the first "]]" in ``raw[start:stop]``, or -1."""
    closes = _closes(raw, start, len(raw) if stop is None else stop)
    return -1 if closes is None else closes[-1] + 1


def _fast(raw: bytes):
    """The parsed JSON with nested-list masks as arrays, or None to fall back."""
    masks: list[np.ndarray] = []
    pieces: list[bytes] = []
    pos = 0
    # searched from each grid's end: scanning megabytes of grid text for the next key costs as much as decoding it
    m = _KEY.search(raw)
    while m is not None:
        start = m.end() - 1
        closes = _closes(raw, start, len(raw))
        if closes is None:
            return None
        end = closes[-1] + 1
        grid = parse_bool_grid(raw, start, end, closes)
        if grid is None:
            grid = parse_grid(raw[start:end])
        if grid is None:
            return None
        pieces += [raw[pos:start], json.dumps(f"{_PLACEHOLDER}{len(masks)}").encode()]
        masks.append(grid)
        pos = end
        m = _KEY.search(raw, end)
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
    if raw.startswith(b"\xef\xbb\xbf"):  # a UTF-8 byte-order mark is not content
        raw = raw[3:]
    data = _fast(raw) if (b'"segmentation"' in raw or b'"mask"' in raw) else None
    return _standard(raw, path) if data is None else data
