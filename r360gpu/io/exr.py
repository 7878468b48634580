"""A small OpenEXR reader (NumPy + zlib) for float depth maps.

Why it exists: the OpenCV wheels r360gpu installs may be built without
OpenEXR (OpenCV 5.0's are), and older ones read EXR only when the
``OPENCV_IO_ENABLE_OPENEXR`` variable was set before the first use.  Depth
renderings are often EXR, so r360gpu reads the common case itself.

Supported: single-part **scanline** files (the usual output of Blender,
nerfstudio, gsplat scripts, OpenEXR's own tools) with channels of type HALF,
FLOAT or UINT, sampling 1x1, compressed with NONE, RLE, ZIPS or ZIP (the
lossless zlib-based codecs; ZIP is OpenEXR's and Blender's default).
Anything else (tiled, multi-part or deep files; PIZ, PXR24, B44, DWA, ...
compression; sub-sampled channels) is an :class:`UnsupportedExrError` whose
message says what is unsupported, so a caller can try another decoder.

Format facts used (OpenEXR file layout, "Reading and Writing OpenEXR Files"
and "OpenEXR File Layout" documents): magic 76 2f 31 01; a 4-byte version
field (bit 9 tiled, bit 11 deep, bit 12 multi-part); attributes ``name\\0
type\\0 int32 size, value`` up to an empty name; a uint64 offset per chunk;
each chunk ``int32 y, int32 size, data`` with the block's scanlines, each
scanline holding every channel (alphabetical order) in turn, little-endian.
ZIP/ZIPS/RLE apply a byte predictor and split even/odd bytes before
compressing; a chunk whose compressed size is not smaller than the raw size
is stored raw.
"""
from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..util.filehash import read_file
from .paths import read_error

#: Decoded images (and EXR data windows) larger than this many pixels are refused before decoding
#: (an 8192 x 8192 view; a few kilobytes of PNG can claim a size whose decoding takes gigabytes).
#: The bundle check also bounds every rendering and mask by its view's size from the headers.
MAX_PIXELS = 1 << 26

_MAGIC = b"\x76\x2f\x31\x01"
_TILED, _DEEP, _MULTIPART = 0x200, 0x800, 0x1000
_COMPRESSION_NAMES = ["NONE", "RLE", "ZIPS", "ZIP", "PIZ", "PXR24", "B44", "B44A", "DWAA", "DWAB",
                      "HTJ2K256", "HTJ2K32"]
# Scanlines per chunk of the codecs this reader decodes.
_LINES_PER_CHUNK = {"NONE": 1, "RLE": 1, "ZIPS": 1, "ZIP": 16}
_PIXEL_TYPES = {0: ("uint", np.dtype("<u4")), 1: ("half", np.dtype("<f2")), 2: ("float", np.dtype("<f4"))}
_PIXEL_TYPES_BY_NAME = {name: dt for name, dt in _PIXEL_TYPES.values()}
# The header is read in one go; real headers are a few hundred bytes.
_MAX_HEADER_BYTES = 1 << 20


class UnsupportedExrError(InputError):
    """A valid EXR file using a feature this reader does not decode."""


@dataclass(frozen=True)
class ExrInfo:
    """Header facts of a scanline EXR file.

    ``channels`` maps each channel name to its pixel type ("uint", "half",
    "float"), in file (alphabetical) order; ``width``/``height`` are the data
    window's size in pixels; ``compression`` is OpenEXR's codec name.
    """

    width: int
    height: int
    channels: dict[str, str]
    compression: str
    x_min: int
    y_min: int
    header_bytes: int


def read_exr_info(path: str | os.PathLike) -> ExrInfo:
    """Parse only the header of an EXR file (cheap: the first bytes of the file).

    Raises InputError when the file is not a readable EXR file and
    UnsupportedExrError for tiled, deep or multi-part files and sub-sampled
    channels.  The compression is reported, not checked (see :func:`read_exr`).
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            head = f.read(_MAX_HEADER_BYTES)
    except OSError as e:
        raise InputError(f"cannot read file: {e.strerror or e}", path) from None
    return _parse_header(head, path)


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Decode every channel of an EXR file.

    Returns ``{channel name: float32 array (height, width)}`` in file order
    (HALF values widened exactly, UINT values converted to float32).  Raises
    InputError naming the file for unreadable or corrupt files and
    UnsupportedExrError (an InputError) for features outside the supported
    subset listed in the module docstring.
    """
    path = os.fspath(path)
    try:
        data = read_file(path)  # hashed as read (util.filehash): the cache key is what was decoded
    except OSError as e:
        raise read_error(e, path) from None
    info = _parse_header(data, path)
    if info.compression not in _LINES_PER_CHUNK:
        raise UnsupportedExrError(
            f"EXR compression {info.compression} is not supported by r360gpu's built-in EXR reader "
            f"(it reads NONE, RLE, ZIPS and ZIP)", path)
    dtypes = [_PIXEL_TYPES_BY_NAME[t] for t in info.channels.values()]
    row_bytes = sum(dt.itemsize for dt in dtypes) * info.width
    lines = _LINES_PER_CHUNK[info.compression]
    n_chunks = -(-info.height // lines)
    table_end = info.header_bytes + 8 * n_chunks
    if len(data) < table_end:
        raise InputError("truncated EXR file (offset table incomplete)", path)
    offsets = np.frombuffer(data, dtype="<u8", count=n_chunks, offset=info.header_bytes)
    out = {name: np.zeros((info.height, info.width), dtype=np.float32) for name in info.channels}
    filled = np.zeros(info.height, dtype=bool)
    for offset in offsets.tolist():
        if offset < table_end or offset + 8 > len(data):
            raise InputError(f"corrupt EXR file (chunk offset {offset} outside the file)", path)
        y, size = struct.unpack_from("<ii", data, offset)
        row0 = y - info.y_min
        n_rows = min(lines, info.height - row0)
        if row0 < 0 or n_rows <= 0 or row0 % lines:
            raise InputError(f"corrupt EXR file (chunk at scanline {y} outside the data window)", path)
        if size < 0 or offset + 8 + size > len(data):
            raise InputError(f"truncated EXR file (chunk at scanline {y})", path)
        raw_size = n_rows * row_bytes
        block = _decompress(data[offset + 8: offset + 8 + size], raw_size, info.compression, path, y)
        _scatter(block, n_rows, info.width, list(info.channels), dtypes, out, row0)
        filled[row0:row0 + n_rows] = True
    if not filled.all():
        raise InputError(f"corrupt EXR file ({int((~filled).sum())} scanlines missing)", path)
    return out


def _parse_header(data: bytes, path: str) -> ExrInfo:
    if len(data) < 8 or data[:4] != _MAGIC:
        raise InputError("not an OpenEXR file (bad magic number)", path)
    (version,) = struct.unpack_from("<I", data, 4)
    # Version 2 with only the tiled / long-names / deep / multi-part flags: anything else is not a
    # header OpenEXR ever wrote (garbage after a valid magic), not an unsupported feature.
    if version & 0xFF != 2 or version & ~0x1EFF:
        raise InputError(f"corrupt EXR file (invalid version field 0x{version:08x} after the magic number)", path)
    if version & _MULTIPART:
        raise UnsupportedExrError("multi-part EXR files are not supported; save a single-part file", path)
    if version & _DEEP:
        raise UnsupportedExrError("deep EXR files are not supported", path)
    if version & _TILED:
        raise UnsupportedExrError("tiled EXR files are not supported; save a scanline file", path)
    pos = 8
    attrs: dict[str, tuple[str, bytes]] = {}
    while True:
        name, pos = _cstring(data, pos, path)
        if not name:
            break
        type_name, pos = _cstring(data, pos, path)
        if pos + 4 > len(data):
            raise InputError("truncated EXR header", path)
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        if size < 0 or pos + size > len(data):
            raise InputError(f"truncated EXR header (attribute {name!r})", path)
        attrs[name] = (type_name, data[pos:pos + size])
        pos += size
    for required in ("channels", "compression", "dataWindow"):
        if required not in attrs:
            raise InputError(f"EXR header has no {required!r} attribute", path)
    channels = _parse_channels(attrs["channels"][1], path)
    comp = attrs["compression"][1]
    if len(comp) != 1 or comp[0] >= len(_COMPRESSION_NAMES):
        raise InputError("EXR header has an unknown compression value", path)
    window = attrs["dataWindow"][1]
    if len(window) != 16:
        raise InputError("EXR header has a malformed dataWindow", path)
    x_min, y_min, x_max, y_max = struct.unpack("<iiii", window)
    width, height = x_max - x_min + 1, y_max - y_min + 1
    if width <= 0 or height <= 0:
        raise InputError(f"EXR data window is empty ({width}x{height})", path)
    if width * height > MAX_PIXELS:  # checked before a pixel is allocated (a header edit can claim 2^31)
        raise InputError(f"EXR data window is {width}x{height}, more pixels than r360gpu decodes ({MAX_PIXELS})",
                         path)
    return ExrInfo(width, height, channels, _COMPRESSION_NAMES[comp[0]], x_min, y_min, pos)


def _cstring(data: bytes, pos: int, path: str) -> tuple[str, int]:
    end = data.find(b"\0", pos)
    if end < 0:
        raise InputError("truncated EXR header", path)
    return data[pos:end].decode("latin-1"), end + 1


def _parse_channels(blob: bytes, path: str) -> dict[str, str]:
    channels: dict[str, str] = {}
    pos = 0
    while True:
        name, pos = _cstring(blob, pos, path)
        if not name:
            break
        if pos + 16 > len(blob):
            raise InputError("malformed EXR channel list", path)
        pixel_type, _, x_sampling, y_sampling = struct.unpack_from("<iIii", blob, pos)
        pos += 16
        if pixel_type not in _PIXEL_TYPES:
            raise InputError(f"EXR channel {name!r} has unknown pixel type {pixel_type}", path)
        if (x_sampling, y_sampling) != (1, 1):
            raise UnsupportedExrError(f"EXR channel {name!r} is sub-sampled ({x_sampling}x{y_sampling})", path)
        channels[name] = _PIXEL_TYPES[pixel_type][0]
    if not channels:
        raise InputError("EXR file has no channels", path)
    return channels


def _decompress(blob: bytes, raw_size: int, compression: str, path: str, y: int) -> np.ndarray:
    # Every codec stores a chunk raw when compressing would not make it smaller.
    if compression == "NONE" or len(blob) == raw_size:
        if len(blob) != raw_size:
            raise InputError(f"corrupt EXR file (chunk at scanline {y} has {len(blob)} bytes, "
                             f"expected {raw_size})", path)
        return np.frombuffer(blob, dtype=np.uint8)
    if compression in ("ZIP", "ZIPS"):
        try:
            packed = zlib.decompress(blob)
        except zlib.error as e:
            raise InputError(f"corrupt EXR file (chunk at scanline {y}: {e})", path) from None
    else:
        packed = _unrle(blob, raw_size, path, y)
    if len(packed) != raw_size:
        raise InputError(f"corrupt EXR file (chunk at scanline {y} decodes to {len(packed)} bytes, "
                         f"expected {raw_size})", path)
    return _unpredict(np.frombuffer(packed, dtype=np.uint8))


def _unrle(blob: bytes, raw_size: int, path: str, y: int) -> bytes:
    # OpenEXR's RLE: a signed count byte n; n < 0: -n literal bytes follow;
    # n >= 0: the next byte repeated n + 1 times.
    out = bytearray()
    pos, end = 0, len(blob)
    while pos < end:
        n = blob[pos] - 256 if blob[pos] > 127 else blob[pos]
        pos += 1
        if n < 0:
            out += blob[pos:pos - n]
            pos -= n
        else:
            if pos >= end:
                break
            out += bytes((blob[pos],)) * (n + 1)
            pos += 1
        if len(out) > raw_size:
            break
    if pos > end:
        raise InputError(f"corrupt EXR file (RLE chunk at scanline {y} is truncated)", path)
    return bytes(out)


def _unpredict(t: np.ndarray) -> np.ndarray:
    # Undo the predictor (each byte stored as the difference to the previous
    # one plus 128, modulo 256), then re-interleave: the first half of the
    # buffer holds the even-indexed bytes, the second half the odd ones.
    d = t.astype(np.int64)
    d[1:] -= 128
    t = (np.cumsum(d) & 0xFF).astype(np.uint8)
    half = (len(t) + 1) // 2
    out = np.empty_like(t)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out


def _scatter(block: np.ndarray, n_rows: int, width: int, names: list[str], dtypes: list[np.dtype],
             out: dict[str, np.ndarray], row0: int) -> None:
    pos = 0
    for r in range(n_rows):
        for name, dt in zip(names, dtypes):
            n_bytes = width * dt.itemsize
            out[name][row0 + r] = block[pos:pos + n_bytes].view(dt)
            pos += n_bytes
