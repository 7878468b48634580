"""Pre-rendered views of a reconstruction: folders of RGB and depth images, one file per view.

For methods that are not 3D Gaussian splats (NeRFs, meshes, 2D-first
pipelines) or whose renderer must be their own, r360gpu reads renderings
instead of rendering.  A renders source is

* an RGB folder: ``<view>.png`` / ``.jpg`` / ``.jpeg``, 8- or 16-bit, grey,
  RGB or RGBA (alpha is dropped: the colour channels are the rendering as
  seen, over whatever background the renderer used);
* optionally a depth folder: ``<view>.png`` (8- or 16-bit integers),
  ``.exr`` (float; see :mod:`.exr`), ``.npy`` (any real dtype) or
  ``.tif`` / ``.tiff`` (e.g. float32).

View names are the file stems (``frame_0001.png`` is view ``frame_0001``).

Depth conventions (those of the renderer's D): camera-space z distance,
0 = no coverage (nothing rendered there).  Non-finite values (some renderers
write +inf or NaN for the background) also mean no coverage and are read as 0;
negative values are an InputError.  Values are multiplied by
``depth_scale`` (e.g. 0.001 for 16-bit PNGs in millimetres).  The geometric
axis thresholds |D_pre - D_post| per view relative to that view's range, so
the unit matters only when two sources of one comparison use different units
(e.g. a splat scene rendered in scene units against depth PNGs in mm): set
``depth_scale`` so that every source of a bundle is in the same unit.

A depth image with several channels is accepted when its colour channels are
identical (grey saved as RGB); a colour-mapped depth visualisation cannot be
turned back into depth and is an InputError.  In an EXR file the depth
channel is the only channel, or the one named ``Z`` or ``depth`` (also as the
last part of a layered name such as ``ViewLayer.Depth.Z``), or identical
colour channels.

EXR decoding uses r360gpu's own reader (:mod:`.exr`: scanline files with
NONE/RLE/ZIPS/ZIP compression).  For other EXR codecs (PIZ, DWA, ...) it
falls back to OpenCV, which reads EXR only when built with OpenEXR and when
the environment variable ``OPENCV_IO_ENABLE_OPENEXR=1`` is set; this module
sets it (unless the user set it) when imported, before OpenCV's EXR codec is
first used, since OpenCV reads the variable at that first use.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path
from types import SimpleNamespace

# OpenCV's EXR codec is disabled unless this is set; OpenCV reads it when the
# codec is first used, so setting it here, before any EXR is decoded, suffices.
os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from ..errors import InputError  # noqa: E402
from ..util.filehash import read_file  # noqa: E402
from .exr import MAX_PIXELS, UnsupportedExrError, read_exr, read_exr_info  # noqa: E402
from .npy import npy_header, read_npy  # noqa: E402
from .paths import link_problem, read_error  # noqa: E402

RGB_EXTENSIONS = (".png", ".jpg", ".jpeg")
DEPTH_EXTENSIONS = (".png", ".exr", ".npy", ".tiff", ".tif")
_DEPTH_CHANNEL_NAMES = ("z", "depth")
_ALPHA_NAMES = ("a", "alpha")
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# JPEG start-of-frame markers (baseline, progressive, lossless, arithmetic ...).
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_HEADER_BYTES = 1 << 16


def read_rgb(path: str | os.PathLike) -> np.ndarray:
    """Read a rendering as float32 (H, W, 3) RGB in [0, 1].

    8-bit images are divided by 255, 16-bit ones by 65535; grey images are
    replicated to three channels; an alpha channel is dropped.  Unreadable or
    undecodable files, and other sample types, are an InputError naming the file.
    """
    img = _decode(path, "image")
    if img.dtype == np.uint8:
        scale = 255.0
    elif img.dtype == np.uint16:
        scale = 65535.0
    else:
        raise InputError(f"RGB rendering has {img.dtype} samples; expected 8- or 16-bit integers", path)
    if img.ndim == 3 and img.shape[2] in (2, 4):
        img = img[:, :, :-1]
    if img.ndim == 2 or img.shape[2] == 1:
        img = np.repeat(img.reshape(img.shape[0], img.shape[1], 1), 3, axis=2)
    elif img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)  # OpenCV decodes to BGR
    else:
        raise InputError(f"RGB rendering has {img.shape[2]} channels", path)
    out = img.astype(np.float32)  # one float image, divided in place
    return np.divide(out, np.float32(scale), out=out)


def read_depth(path: str | os.PathLike, depth_scale: float = 1.0) -> np.ndarray:
    """Read a depth map as float32 (H, W), 0 = no coverage, times ``depth_scale``.

    Formats by extension: ``.png`` (8/16-bit), ``.exr``, ``.npy``, ``.tif`` /
    ``.tiff``; conventions in the module docstring.  Problems (unreadable,
    undecodable, colour-mapped, negative values, unknown extension) are an
    InputError naming the file.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        depth = _exr_depth(path)
    elif suffix == ".npy":
        depth = _npy_depth(path)
    elif suffix in (".png", ".tif", ".tiff"):
        img = _decode(path, "depth image", lossless=True)
        if not (np.issubdtype(img.dtype, np.integer) or np.issubdtype(img.dtype, np.floating)):
            raise InputError(f"depth image has {img.dtype} samples", path)
        if img.ndim == 3:
            img = _single_channel([img[:, :, c] for c in range(img.shape[2] - (img.shape[2] in (2, 4)))],
                                  path)
        depth = img
    else:
        raise InputError(f"unknown depth format {suffix or '(no extension)'!r}; expected one of "
                         f"{', '.join(DEPTH_EXTENSIONS)}", path)
    depth = np.asarray(depth, dtype=np.float32)
    finite = np.isfinite(depth)
    if not finite.all():
        depth = np.where(finite, depth, np.float32(0.0))
    if depth.size and float(depth.min()) < 0:
        raise InputError(f"depth has negative values (min {float(depth.min()):.6g}); expected distances "
                         f">= 0 with 0 = no coverage", path)
    if depth_scale != 1.0:
        depth = depth * np.float32(depth_scale)
    return np.ascontiguousarray(depth, dtype=np.float32)


def image_size(path: str | os.PathLike) -> tuple[int, int]:
    """(height, width) of an image file from its header, without decoding the pixels.

    Headers are parsed for PNG, JPEG, EXR, NPY and TIFF; other formats are
    decoded with OpenCV.  A file whose header is unreadable or malformed is an
    InputError (a valid header does not guarantee decodable pixel data).
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        info = read_exr_info(path)
        return info.height, info.width
    if suffix == ".npy":
        return _npy_hw(_npy_shape(path), path)
    head = _read_head(path)
    if head.startswith(_PNG_SIGNATURE):
        if len(head) < 24 or head[12:16] != b"IHDR":
            raise InputError("malformed PNG header (no IHDR chunk)", path)
        w, h = struct.unpack(">II", head[16:24])
        return _checked_hw(h, w, path)
    if head.startswith(b"\xff\xd8"):
        return _jpeg_size(head, path)
    if head[:4] in (b"II*\x00", b"MM\x00*"):
        size = _tiff_size(path)
        if size is not None:
            return size
    return _decode(path, "image").shape[:2]


_JPEG_MAGIC = b"\xff\xd8\xff"
#: Extensions of lossy formats: a depth file in one is named in the "missing depth" message.
LOSSY_EXTENSIONS = (".jpg", ".jpeg", ".webp")


def refuse_lossy(head: bytes, path, what: str) -> None:
    """InputError when ``head`` starts JPEG data (whatever the file's extension): lossy compression
    changes the values a depth map or a mask is read for."""
    if head.startswith(_JPEG_MAGIC):
        raise InputError(f"{what} holds JPEG data (whatever its extension): JPEG compression changes the values "
                         f"around every edge; save it in a lossless format (16-bit PNG, EXR, NPY or TIFF for "
                         f"depth, PNG for masks)", path)


def check_pixel_count(head: bytes, path, what: str = "image") -> None:
    """InputError when the header in ``head`` (PNG or JPEG) claims more than :data:`MAX_PIXELS` pixels."""
    hw = None
    if head.startswith(_PNG_SIGNATURE) and len(head) >= 24 and head[12:16] == b"IHDR":
        hw = struct.unpack(">II", head[16:24])[::-1]
    elif head.startswith(b"\xff\xd8"):
        try:
            hw = _jpeg_size(head, path, decode=False)
        except InputError:
            hw = None
    if hw is not None and hw[0] * hw[1] > MAX_PIXELS:
        raise InputError(f"{what} claims {hw[1]}x{hw[0]} pixels, more than r360gpu decodes ({MAX_PIXELS}); "
                         f"not a rendering of an evaluation view", path)


def check_png_chunks(raw, path, what: str = "image") -> None:
    """InputError when a PNG's chunk lengths run past the end of the file.  OpenCV allocates what a
    chunk length claims before it reads it: a 100-byte file claiming a 2 GB chunk took 8 s and
    gigabytes; walking the chunk headers first costs microseconds."""
    data = raw.tobytes() if isinstance(raw, np.ndarray) else bytes(raw)
    if not data.startswith(_PNG_SIGNATURE):
        return
    pos, n = len(_PNG_SIGNATURE), len(data)
    while pos + 8 <= n:
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        if pos + 12 + length > n:
            raise InputError(f"corrupt or truncated PNG {what}: chunk {kind!r} at byte {pos} claims {length} "
                             f"bytes, the file has {max(0, n - pos - 12)} left", path)
        if kind == b"IEND":
            return
        pos += 12 + length


def depth_size(path: str | os.PathLike) -> tuple[int, int]:
    """(height, width) of a depth file from its header, with the refusal :func:`read_depth` makes from
    the header (JPEG data in a .png or .tiff)."""
    if Path(path).suffix.lower() in (".png", ".tif", ".tiff"):
        refuse_lossy(_read_head(path)[:3], path, "depth image")
    return image_size(path)


class RendersReader:
    """Reads the renderings of one renders source.

    ``spec`` is any object with ``rgb_dir``, ``depth_dir`` (None: no depth)
    and ``depth_scale`` attributes, e.g. :class:`r360gpu.bundle.SourceSpec`
    of kind "renders".  The folders are listed once, when the reader is made.

    Raises InputError when the RGB folder (or a given depth folder) does not
    exist or ``depth_scale`` is not a positive finite number.
    """

    def __init__(self, spec) -> None:
        if spec.rgb_dir is None:
            raise InputError("renders source has no RGB folder", getattr(spec, "path", None))
        self.rgb_dir = Path(spec.rgb_dir)
        self.depth_dir = None if spec.depth_dir is None else Path(spec.depth_dir)
        self.depth_scale = float(spec.depth_scale)
        if not (np.isfinite(self.depth_scale) and self.depth_scale > 0):
            raise InputError(f"depth_scale must be a positive number, got {spec.depth_scale!r}",
                             getattr(spec, "path", None))
        self._rgb = _index(self.rgb_dir, RGB_EXTENSIONS, "RGB")
        self._depth = None if self.depth_dir is None else _index(self.depth_dir, DEPTH_EXTENSIONS, "depth")
        # depth files in a lossy format are not read, but named when their view has no depth
        self._lossy_depth = ({} if self.depth_dir is None
                             else _index(self.depth_dir, LOSSY_EXTENSIONS, "depth"))

    @classmethod
    def from_dirs(cls, rgb_dir: str | os.PathLike, depth_dir: str | os.PathLike | None = None,
                  depth_scale: float = 1.0) -> "RendersReader":
        """A reader for explicit folders (no SourceSpec needed)."""
        return cls(SimpleNamespace(rgb_dir=rgb_dir, depth_dir=depth_dir, depth_scale=depth_scale))

    @property
    def has_depth(self) -> bool:
        """True when the source has a depth folder."""
        return self._depth is not None

    def views(self) -> list[str]:
        """Sorted names of the views with an RGB image."""
        return sorted(self._rgb)

    def depth_views(self) -> list[str]:
        """Sorted names of the views with a depth image ([] without a depth folder)."""
        return sorted(self._depth or {})

    def rgb_path(self, view: str) -> Path:
        """The RGB file of ``view``; InputError when there is none or more than one."""
        return _lookup(self._rgb, view, self.rgb_dir, RGB_EXTENSIONS, "RGB image")

    def depth_path(self, view: str) -> Path:
        """The depth file of ``view``; InputError when there is none, more than one, or no depth folder."""
        if self._depth is None:
            raise InputError(f"no depth folder, so no depth for view {view!r}", self.rgb_dir.parent)
        try:
            return _lookup(self._depth, view, self.depth_dir, DEPTH_EXTENSIONS, "depth image")
        except InputError as e:
            hint = self.lossy_depth_hint([view])
            raise InputError(f"{e.problem}{'; ' + hint if hint else ''}", e.path) from None

    def lossy_depth_hint(self, views) -> str:
        """"" or a sentence naming the depth files of ``views`` saved in a lossy format (not read)."""
        found = [p.name for v in views for p in self._lossy_depth.get(v, ())]
        if not found:
            return ""
        listed = ", ".join(found[:5]) + (f" and {len(found) - 5} more" if len(found) > 5 else "")
        return (f"found {listed}: depth in JPEG is not read (lossy compression changes the depth values); "
                f"save depth as 16-bit PNG, EXR, NPY or TIFF")

    def rgb(self, view: str) -> np.ndarray:
        """float32 (H, W, 3) RGB in [0, 1] of ``view`` (see :func:`read_rgb`)."""
        return read_rgb(self.rgb_path(view))

    def depth(self, view: str) -> np.ndarray:
        """float32 (H, W) depth of ``view``, 0 = no coverage, times depth_scale (see :func:`read_depth`)."""
        return read_depth(self.depth_path(view), self.depth_scale)

    def size(self, view: str) -> tuple[int, int]:
        """(height, width) of ``view``'s RGB image, from its header."""
        return image_size(self.rgb_path(view))

    def __repr__(self) -> str:
        depth = None if self.depth_dir is None else str(self.depth_dir)
        return (f"RendersReader(rgb_dir={str(self.rgb_dir)!r}, depth_dir={depth!r}, "
                f"depth_scale={self.depth_scale:g}, views={len(self._rgb)})")


def _index(folder: Path, extensions: tuple[str, ...], what: str) -> dict[str, list[Path]]:
    if not folder.is_dir():
        broken = link_problem(folder)
        problem = "is not a folder" if folder.exists() else f"is a {broken}" if broken else "does not exist"
        raise InputError(f"{what} folder {problem}", folder)
    found: dict[str, list[Path]] = {}
    try:
        entries = sorted(os.scandir(folder), key=lambda e: e.name)
    except OSError as e:
        raise InputError(f"cannot list {what} folder: {e.strerror or e}", folder) from None
    for entry in entries:
        p = Path(entry.path)
        # a dangling link is kept: reading it then says what it is, instead of "no image for view"
        if p.suffix.lower() in extensions and not entry.name.startswith(".") and (
                entry.is_file() or link_problem(p)):
            found.setdefault(p.stem, []).append(p)
    return found


def _lookup(index: dict[str, list[Path]], view: str, folder: Path, extensions: tuple[str, ...],
            what: str) -> Path:
    files = index.get(view)
    if not files:
        tried = ", ".join(view + e for e in extensions)
        raise InputError(f"no {what} for view {view!r} (looked for {tried})", folder)
    if len(files) > 1:
        raise InputError(f"several {what}s for view {view!r}: {', '.join(f.name for f in files)}; "
                         f"keep one", folder)
    return files[0]


def _read_bytes(path) -> np.ndarray:
    try:
        return np.frombuffer(read_file(path), dtype=np.uint8)  # hashed as read (util.filehash)
    except OSError as e:
        raise read_error(e, path) from None


def _read_head(path) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(_HEADER_BYTES)
    except OSError as e:
        raise read_error(e, path) from None


def _decode(path, what: str, *, lossless: bool = False) -> np.ndarray:
    raw = _read_bytes(path)
    if lossless:
        refuse_lossy(raw[:3].tobytes(), path, what)
    check_pixel_count(raw[:_HEADER_BYTES].tobytes(), path, what)
    check_png_chunks(raw, path, what)
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise InputError(f"cannot decode {what} (not an image file, or corrupt)", path)
    return img


def _single_channel(channels: list[np.ndarray], path) -> np.ndarray:
    first = channels[0]
    if any(not np.array_equal(first, c, equal_nan=np.issubdtype(c.dtype, np.floating))
           for c in channels[1:]):
        raise InputError(f"depth image has {len(channels)} different colour channels (a colour-mapped "
                         f"visualisation?); save depth as a single channel", path)
    return first


def _exr_depth(path) -> np.ndarray:
    try:
        channels = read_exr(path)
    except UnsupportedExrError as e:
        return _exr_depth_opencv(path, e)
    names = list(channels)
    if len(names) == 1:
        return channels[names[0]]
    last = {n: n.rsplit(".", 1)[-1].lower() for n in names}
    named = [n for n in names if last[n] in _DEPTH_CHANNEL_NAMES]
    if len(named) == 1:
        return channels[named[0]]
    if len(named) > 1:
        raise InputError(f"EXR file has several depth channels ({', '.join(named)}); keep one", path)
    colour = [n for n in names if last[n] not in _ALPHA_NAMES] or names
    try:
        return _single_channel([channels[n] for n in colour], path)
    except InputError:
        raise InputError(f"EXR file has channels {', '.join(names)} and none is named Z or depth; "
                         f"save the depth as a single channel (or name it Z)", path) from None


def _exr_depth_opencv(path, unsupported: UnsupportedExrError) -> np.ndarray:
    hint = ("OpenCV could not read it either: it reads EXR only when built with OpenEXR and with "
            "OPENCV_IO_ENABLE_OPENEXR=1 in the environment when r360gpu starts. Re-save the depth as a "
            "scanline EXR with ZIP or no compression, or as .npy or float32 .tiff")
    try:  # decoded from the bytes read_file hashed (util.filehash), as every other input
        img = cv2.imdecode(np.frombuffer(read_file(path), np.uint8), cv2.IMREAD_UNCHANGED)
    except (cv2.error, OSError):
        img = None
    if img is None:
        raise InputError(f"{unsupported.problem}. {hint}", path) from None
    if img.ndim == 3:
        img = _single_channel([img[:, :, c] for c in range(img.shape[2] - (img.shape[2] in (2, 4)))], path)
    return img


def _npy_shape(path) -> tuple[int, ...]:
    try:
        with open(path, "rb") as f:
            return npy_header(f, path)[0]
    except OSError as e:
        raise read_error(e, path) from None


def _npy_hw(shape: tuple[int, ...], path) -> tuple[int, int]:
    if len(shape) == 2:
        return _checked_hw(shape[0], shape[1], path)
    if len(shape) == 3 and shape[2] == 1:
        return _checked_hw(shape[0], shape[1], path)
    if len(shape) == 3 and shape[0] == 1:
        return _checked_hw(shape[1], shape[2], path)
    raise InputError(f"depth array has shape {shape}; expected (H, W), (H, W, 1) or (1, H, W)", path)


def _npy_depth(path) -> np.ndarray:
    arr = read_npy(path, max_values=MAX_PIXELS)
    if arr.dtype == np.bool_ or not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
        raise InputError(f"depth array has dtype {arr.dtype}; expected real numbers", path)
    h, w = _npy_hw(arr.shape, path)
    return arr.reshape(h, w)


def _checked_hw(h: int, w: int, path) -> tuple[int, int]:
    if h <= 0 or w <= 0:
        raise InputError(f"image is empty ({w}x{h})", path)
    return int(h), int(w)


def _jpeg_size(head: bytes, path, decode: bool = True) -> tuple[int, int] | None:
    pos = 2
    while pos + 4 <= len(head):
        if head[pos] != 0xFF:
            raise InputError("malformed JPEG header", path)
        marker = head[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:  # markers without a length
            pos += 2
            continue
        (length,) = struct.unpack(">H", head[pos + 2:pos + 4])
        if marker in _JPEG_SOF:
            if pos + 9 > len(head):
                break
            h, w = struct.unpack(">HH", head[pos + 5:pos + 9])
            return _checked_hw(h, w, path)
        if marker in (0xD9, 0xDA) or length < 2:
            break
        pos += 2 + length
    # Frame header beyond the bytes read (huge metadata) or malformed: decode.
    return _decode(path, "image").shape[:2] if decode else None


def _tiff_size(path) -> tuple[int, int] | None:
    """(h, w) from a classic TIFF's first IFD, or None when that is not possible (BigTIFF, odd layout)."""
    try:
        with open(path, "rb") as f:
            data = f.read(_HEADER_BYTES)
            e = "<" if data[:2] == b"II" else ">"
            (ifd,) = struct.unpack(e + "I", data[4:8])
            f.seek(ifd)
            (n,) = struct.unpack(e + "H", f.read(2))
            entries = f.read(12 * n)
    except (OSError, struct.error):
        return None
    found: dict[int, int] = {}
    for k in range(len(entries) // 12):
        tag, typ, count = struct.unpack(e + "HHI", entries[12 * k:12 * k + 8])
        if tag in (256, 257) and count == 1 and typ in (3, 4):
            fmt = e + ("H" if typ == 3 else "I")
            (found[tag],) = struct.unpack_from(fmt, entries, 12 * k + 8)
    if 256 in found and 257 in found:
        return _checked_hw(found[257], found[256], path)
    return None
