"""The JPEG a contact sheet is embedded in report.html as, and its cache.

report.html embeds every per-(method, view) contact sheet; made from the PNG
at the end of a run (decode, area resize, JPEG encode) that is seconds of
work nothing overlaps.  So the picture writer makes the same JPEG while it
writes the sheet, from the sheet in memory, and keeps it in a cache folder
keyed by a digest of the PNG's bytes; report.html reads the PNG, digests it
and takes the cached JPEG when there is one.  The PNG is lossless, so the
array in memory is what decoding it gives back and both ways give the same
bytes (tests/test_report_embed.py).  Every entry carries a digest of its name
and bytes: a damaged one is ignored (and rewritten), never embedded.  Which
folder is the cache is the caller's to say (the scoring pipeline passes one
under ``OUT/.r360cache``); without one, everything is made from the PNG.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import cv2
import numpy as np

from ..util.atomic import write_bytes

#: Contact sheets (photographic renders) are embedded as JPEG of this quality,
#: at most EMBED_WIDTH pixels wide: a few per cent of the PNG's size, which
#: keeps a report with dozens of views in the low megabytes.  The lossless
#: full-size PNGs stay beside the report.
JPEG_QUALITY = 80
EMBED_WIDTH = 960

#: Everything besides the PNG that decides the JPEG's bytes: a change misses the cache.
_RECIPE = f"r360gpu-embed/2 w{EMBED_WIDTH} q{JPEG_QUALITY} opencv {cv2.__version__}".encode()
_CHECK = 16  # bytes of the entry's own digest, in front of the JPEG


def embed_jpeg(bgr: np.ndarray) -> bytes | None:
    """JPEG bytes of a decoded contact sheet (uint8 BGR, as ``cv2.imdecode`` gives it), at most
    :data:`EMBED_WIDTH` px wide, quality :data:`JPEG_QUALITY`; None if OpenCV fails.

    Sheets are reduced by less than 2x (1180-1610 px to 960): bilinear
    interpolation then reads every source pixel, and OpenCV's area averaging
    at such fractional factors costs about 7x as much (bench/bench_pictures.py
    times both and prints how far apart they are: ~0.6 grey levels on average
    on its sheets; under 1.5 on the noisy panels of tests/test_report_embed.py);
    from 2x on it averages areas."""
    if bgr.shape[1] > EMBED_WIDTH:
        h = max(1, round(bgr.shape[0] * EMBED_WIDTH / bgr.shape[1]))
        interp = cv2.INTER_LINEAR if bgr.shape[1] < 2 * EMBED_WIDTH else cv2.INTER_AREA
        bgr = cv2.resize(bgr, (EMBED_WIDTH, h), interpolation=interp)
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    return buf.tobytes() if ok else None


def jpeg_from_png(png: bytes) -> bytes | None:
    """:func:`embed_jpeg` of a PNG file's bytes (None when it does not decode)."""
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    return None if img is None else embed_jpeg(img)


def _entry(folder: str | os.PathLike, png: bytes) -> Path:
    h = hashlib.blake2b(_RECIPE + b"\0", digest_size=20)
    h.update(png)
    return Path(folder) / f"{h.hexdigest()}.jpg"


def _check(entry: Path, jpeg: bytes) -> bytes:
    # bound to the entry's name too: the JPEG of another sheet under this name is no match
    h = hashlib.blake2b(entry.name.encode() + b"\0", digest_size=_CHECK)
    h.update(jpeg)
    return h.digest()


def store_embed(folder: str | os.PathLike, png: bytes, jpeg: bytes) -> None:
    """Keep ``jpeg`` as the embedding of the sheet whose PNG bytes are ``png``.

    A cache entry is regenerable: written atomically without fsync, and a
    write that fails (read-only or full disk) is skipped."""
    try:
        entry = _entry(folder, png)
        write_bytes(entry, _check(entry, jpeg) + jpeg, sync=False)
    except OSError:
        pass


def load_embed(folder: str | os.PathLike, png: bytes) -> bytes | None:
    """The cached JPEG of the sheet whose PNG bytes are ``png``; None when absent or damaged."""
    entry = _entry(folder, png)
    try:
        data = entry.read_bytes()
    except OSError:
        return None
    jpeg = data[_CHECK:]
    return jpeg if len(data) > _CHECK and data[:_CHECK] == _check(entry, jpeg) else None


def sheet_jpeg(png: bytes, folder: str | os.PathLike | None = None) -> bytes | None:
    """The embedding JPEG of a sheet's PNG bytes: from the cache ``folder`` when it has it, else made
    from the PNG (and stored there); None when the PNG does not decode."""
    if folder is not None:
        hit = load_embed(folder, png)
        if hit is not None:
            return hit
    jpeg = jpeg_from_png(png)
    if jpeg is not None and folder is not None:
        store_embed(folder, png, jpeg)
    return jpeg
