"""Per-view pictures: panels (RGB, depth change, changed mask, probe masks) and contact sheets.

Every panel is a uint8 (h, w, 3) RGB image.  The helpers take full-resolution
inputs and return a panel ``width`` pixels wide (aspect kept; shrinking uses
area averaging, enlarging nearest neighbour, masks always nearest neighbour),
so lines and labels are drawn at the final resolution.  A contact sheet lays
titled panels out on a grid and is written as PNG (OpenCV only; text with the
Hershey font, ASCII).

Colours: target outline green; semantic prediction magenta; structural
masks random colours from a seeded generator (same input -> same picture);
depth change with the "inferno" colour map over a colour bar whose cyan
tick marks the GHT threshold t_depth (not the IoU threshold xi of acc_seg).
A view's contact sheet carries its numbers under the title (so they survive
copying the picture) and a legend of every colour at the bottom.
"""
from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..protocol import XI_DEFAULT
from ..util.atomic import write_bytes
from ..util.resize import resize_nearest
from ..util.memo import ByIdentity
from . import png

#: Default panel width (px): keeps the report light.
PANEL_WIDTH = 320
#: Narrowest panel a view's sheet gets: four of them keep the lines of numbers under the title whole.
MIN_PANEL_WIDTH = 240
TARGET_RGB = (0, 230, 0)
SEMANTIC_RGB = (255, 0, 255)
THRESHOLD_RGB = (0, 255, 255)
CHANGED_IN_TARGET_RGB = (255, 215, 0)
CHANGED_OUTSIDE_RGB = (165, 165, 165)
MISSED_IN_TARGET_RGB = (110, 25, 25)
#: In M with no depth after removal (nothing rendered there: a see-through hole).
NO_DEPTH_IN_TARGET_RGB = (40, 120, 255)
BACKGROUND_RGB = (35, 35, 35)

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_TITLE_SCALE = 0.42
_TITLE_H = 18
_PAD = 4


def panel_width_for(image_width: int) -> int:
    """Panel width for a view ``image_width`` px wide: :data:`PANEL_WIDTH`, or the view's own
    width when that is smaller (no enlarged pixels, less to encode), but at least
    :data:`MIN_PANEL_WIDTH`."""
    return max(MIN_PANEL_WIDTH, min(PANEL_WIDTH, int(image_width)))


# -- conversion ----------------------------------------------------------------

def as_rgb8(image, what: str = "image") -> np.ndarray:
    """uint8 (H, W, 3) RGB from uint8 / float [0, 1] RGB, gray (H, W) or a bool mask.

    Float values are clipped to [0, 1] (non-finite -> 0); bool masks become
    white on black.
    """
    a = _image_array(image, what)
    if a.dtype == bool:
        a = a.astype(np.uint8) * 255
    elif a.dtype != np.uint8:
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise InputError(f"{what}: unsupported dtype {a.dtype}")
        # fmax/fmin return the number where the other is NaN: NaN -> 0, +inf -> 1, -inf -> 0
        f = np.fmax(a, np.float32(0.0), dtype=np.float32)
        np.fmin(f, np.float32(1.0), out=f)
        f *= np.float32(255.0)
        a = np.rint(f, out=f).astype(np.uint8)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    return np.ascontiguousarray(a)


def _image_array(image, what: str) -> np.ndarray:
    """(H, W) or (H, W, 3) view of an image (a single channel squeezed, alpha dropped); InputError otherwise."""
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] not in (3, 4)) or a.shape[0] < 1 or a.shape[1] < 1:
        raise InputError(f"{what}: expected an (H, W) or (H, W, 3) image, got shape {a.shape}")
    return a[:, :, :3] if a.ndim == 3 and a.shape[2] == 4 else a


def rgb8_at(image, width: int, what: str = "image") -> np.ndarray:
    """:func:`as_rgb8` of ``image`` at ``width`` px wide (aspect kept; area average down, nearest up).

    Float images are resized first and quantised after: one rounding of the
    averaged value, and the float-to-8-bit pass made at panel size (the
    panels of 1200 x 1000 renders 2.5x faster, bench/bench_pictures.py).  Where the
    average meets a non-finite value the image is quantised first instead, so
    NaN and inf read as :func:`as_rgb8` reads them (0 and 1).
    """
    a = _image_array(image, what)
    if a.dtype in (np.float32, np.float64) and a.shape[1] != width:
        small = _resize_rgb(a, width)
        if np.isfinite(small).all():
            return as_rgb8(small, what)
    return _resize_rgb(as_rgb8(a, what), width)


def _mask(m, what: str) -> np.ndarray:
    a = np.asarray(m)
    if a.ndim != 2:
        raise InputError(f"{what}: expected an (H, W) mask, got shape {a.shape}")
    return a != 0


def _stack(masks, what: str) -> np.ndarray:
    """bool (K, H, W) from (K, H, W) / (H, W) masks or an object with a ``masks`` attribute."""
    if masks is None:
        return np.zeros((0, 1, 1), bool)
    a = np.asarray(getattr(masks, "masks", masks))
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3:
        raise InputError(f"{what}: expected (K, H, W) masks, got shape {a.shape}")
    return a != 0


def panel_size(shape: tuple[int, int], width: int) -> tuple[int, int]:
    """(w, h) for cv2.resize: ``width`` wide, aspect kept (height at least 1)."""
    h, w = shape
    return int(width), max(1, int(round(h * width / w)))


def _resize_rgb(rgb: np.ndarray, width: int) -> np.ndarray:
    if rgb.shape[1] == width:
        return rgb
    interp = cv2.INTER_AREA if width < rgb.shape[1] else cv2.INTER_NEAREST
    return cv2.resize(rgb, panel_size(rgb.shape[:2], width), interpolation=interp)


def resize_mask(mask: np.ndarray, size_wh: tuple[int, int]) -> np.ndarray:
    """A bool mask at panel size ``(w, h)`` by the project's nearest rule (:mod:`r360gpu.util.resize`)."""
    return resize_nearest(mask, (size_wh[1], size_wh[0]))


def _check_width(width: int) -> int:
    w = int(width)
    if w < 16:
        raise InputError(f"panel width must be at least 16 px, got {width!r}")
    return w


def _outline(img: np.ndarray, mask: np.ndarray, rgb: tuple[int, int, int], thickness: int = 1) -> None:
    """Draw the outer and hole boundaries of ``mask`` on ``img`` in place."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    if contours:
        cv2.drawContours(img, contours, -1, tuple(int(c) for c in rgb), thickness, lineType=cv2.LINE_8)


def _ascii(text: str) -> str:
    return "".join(ch if 32 <= ord(ch) < 127 else "?" for ch in str(text))


def _put_text(img: np.ndarray, text: str, org: tuple[int, int], rgb=(0, 0, 0), scale: float = _TITLE_SCALE,
              max_width: int | None = None) -> None:
    """Draw one line of text (ASCII; shortened with '..' to fit ``max_width``)."""
    t = _ascii(text)
    if max_width is not None:
        while t and cv2.getTextSize(t, _FONT, scale, 1)[0][0] > max_width:
            t = t[:-3] + ".." if len(t) > 3 else ""
    cv2.putText(img, t, org, _FONT, scale, tuple(int(c) for c in rgb), 1, cv2.LINE_AA)


# -- panels --------------------------------------------------------------------

def rgb_panel(image, width: int = PANEL_WIDTH, *, target=None) -> np.ndarray:
    """An RGB rendering as a panel ``width`` px wide, optionally with the target outline (green)."""
    width = _check_width(width)
    img = rgb8_at(image, width, "RGB panel").copy()
    if target is not None:
        t = _mask(target, "target mask")
        _outline(img, resize_mask(t, (img.shape[1], img.shape[0])), TARGET_RGB)
    return img


def depth_change_panel(delta, threshold: float | None, width: int = PANEL_WIDTH, *,
                       vmax: float | None = None) -> np.ndarray:
    """Heat map of the depth change |dD| above a colour bar that marks the threshold.

    delta: float (H, W) |D_pre - D_post| (non-finite values shown as 0).
    threshold: the GHT threshold t_depth in the units of ``delta``: a cyan tick on the colour
        bar (pixels above it count as changed); None draws no tick.
    width: panel width in px (heat map and bar).
    vmax: top of the colour scale (default: the largest finite |dD|; 1 when
        that is 0).

    Returns uint8 (h, width, 3) RGB: the heat map, then a 26 px strip with the
    colour bar (0 on the left, vmax on the right) and its labels.
    """
    width = _check_width(width)
    d = np.asarray(delta)
    if d.ndim != 2:
        raise InputError(f"depth change: expected an (H, W) array, got shape {d.shape}")
    d = np.abs(d.astype(np.float32))
    largest = float(d.max(initial=0.0))
    if not np.isfinite(largest):  # NaN or inf somewhere: shown as 0
        d = np.nan_to_num(d, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        largest = float(d.max(initial=0.0))
    top = float(vmax) if vmax is not None else largest
    if not top > 0:
        top = 1.0
    # |dD| brought to the panel size first, then coloured: the colour of the averaged change
    level = np.rint(np.clip(_resize_rgb(d, width) / np.float32(top), 0.0, 1.0) * 255.0).astype(np.uint8)
    heat = cv2.cvtColor(cv2.applyColorMap(level, cv2.COLORMAP_INFERNO), cv2.COLOR_BGR2RGB)
    strip_h, bar_h = 26, 8
    panel = np.full((heat.shape[0] + strip_h, width, 3), 255, np.uint8)
    panel[: heat.shape[0]] = heat
    y0 = heat.shape[0] + 3
    ramp = np.linspace(0, 255, width).astype(np.uint8)[None, :]
    bar = cv2.cvtColor(cv2.applyColorMap(np.repeat(ramp, bar_h, axis=0), cv2.COLORMAP_INFERNO), cv2.COLOR_BGR2RGB)
    panel[y0 : y0 + bar_h] = bar
    ty = y0 + bar_h + 12
    _put_text(panel, "0", (1, ty), scale=0.33)
    top_text = f"{top:.3g}"
    tw = cv2.getTextSize(top_text, _FONT, 0.33, 1)[0][0]
    _put_text(panel, top_text, (width - tw - 1, ty), scale=0.33)
    if threshold is not None and np.isfinite(threshold):
        x = int(round(min(max(float(threshold) / top, 0.0), 1.0) * (width - 1)))
        cv2.line(panel, (x, y0 - 3), (x, y0 + bar_h + 1), THRESHOLD_RGB, 2)
        label = f"t_depth {float(threshold):.3g}"
        lw = cv2.getTextSize(label, _FONT, 0.33, 1)[0][0]
        # Beside the tick, on the side with room, clear of the "0" and vmax labels.
        lx = max(x + 5, 12)
        if lx + lw > width - tw - 4:
            lx = max(12, x - lw - 5)
        _put_text(panel, label, (lx, ty), rgb=(0, 120, 140), scale=0.33)
    return panel


def changed_panel(changed, target, width: int = PANEL_WIDTH, no_depth=None) -> np.ndarray:
    """The changed-pixel mask against the target.

    changed: (H, W) bool, |dD| > t_depth (the GHT threshold).  target: (H, W) target mask M
    (non-zero = target).  no_depth: (H, W) bool, no depth after removal (D_post
    missing), or None.  Colours: changed inside M yellow (what acc_depth
    counts), unchanged inside M dark red (missed), inside M with no depth after
    removal blue (a see-through hole: dD is 0 there by the missing-depth rule, so
    acc_depth does not count it either), changed outside M grey, the rest dark;
    the outline of M in green.
    """
    width = _check_width(width)
    c = _mask(changed, "changed mask")
    t = _mask(target, "target mask")
    if c.shape != t.shape:
        raise InputError(f"changed mask is {c.shape[0]}x{c.shape[1]} but the target is {t.shape[0]}x{t.shape[1]}")
    size = panel_size(c.shape, width)
    nd = None
    if no_depth is not None:
        nd = _mask(no_depth, "no-depth mask")
        if nd.shape != t.shape:
            raise InputError(f"no-depth mask is {nd.shape[0]}x{nd.shape[1]} but the target is "
                             f"{t.shape[0]}x{t.shape[1]}")
        nd = resize_mask(nd, size)
    c, t = resize_mask(c, size), resize_mask(t, size)
    img = np.empty((size[1], size[0], 3), np.uint8)
    img[:] = BACKGROUND_RGB
    img[c & ~t] = CHANGED_OUTSIDE_RGB
    img[~c & t] = MISSED_IN_TARGET_RGB
    if nd is not None:
        img[~c & t & nd] = NO_DEPTH_IN_TARGET_RGB
    img[c & t] = CHANGED_IN_TARGET_RGB
    _outline(img, t, TARGET_RGB)
    return img


def no_depth_fraction(no_depth, target) -> float | None:
    """Fraction of the target mask M with no depth after removal (None when M is empty)."""
    t = _mask(target, "target mask")
    nd = _mask(no_depth, "no-depth mask")
    if nd.shape != t.shape:
        raise InputError(f"no-depth mask is {nd.shape[0]}x{nd.shape[1]} but the target is {t.shape[0]}x{t.shape[1]}")
    n = int(t.sum())
    return float((nd & t).sum()) / n if n else None


def mask_colors(n: int, seed: int = 0) -> np.ndarray:
    """uint8 (n, 3) bright random RGB colours from ``default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    hsv = np.stack([rng.integers(0, 180, n), rng.integers(150, 256, n), rng.integers(170, 256, n)], axis=1)
    return cv2.cvtColor(hsv.astype(np.uint8)[None], cv2.COLOR_HSV2RGB)[0] if n else np.zeros((0, 3), np.uint8)


def mask_overlay(rgb, masks, width: int = PANEL_WIDTH, *, color: tuple[int, int, int] | None = None,
                 alpha: float = 0.45, target=None, seed: int = 0) -> np.ndarray:
    """Probe masks blended over an RGB rendering, each with its outline.

    rgb: the rendering ((H, W, 3) uint8 or float [0, 1]).
    masks: (H, W) mask or (K, H, W) stack (or an object with ``.masks``), or None.
    color: one RGB colour for every mask (e.g. the semantic prediction);
        None gives each mask its own random colour (seeded by ``seed``).
    alpha: blend weight of the mask colour.
    target: optional (H, W) target mask, outlined in green on top.
    """
    width = _check_width(width)
    full_hw = _image_array(rgb, "overlay image").shape[:2]
    img = rgb8_at(rgb, width, "overlay image").astype(np.float32)
    size = (img.shape[1], img.shape[0])
    stack = _stack(masks, "overlay masks")
    if stack.shape[0] and stack.shape[1:] != full_hw:
        raise InputError(f"overlay masks are {stack.shape[1]}x{stack.shape[2]} but the image is "
                         f"{full_hw[0]}x{full_hw[1]}")
    colors = (np.tile(np.array(color, np.uint8), (stack.shape[0], 1)) if color is not None
              else mask_colors(stack.shape[0], seed))
    small = [resize_mask(m, size).astype(np.uint8) for m in stack]
    keep = np.float32(1.0 - alpha)
    for m, col in zip(small, colors):
        # blended within the mask's bounding box only, and written where the mask is
        x, y, bw, bh = cv2.boundingRect(m)
        if bw and bh:
            box = img[y : y + bh, x : x + bw]
            np.copyto(box, box * keep + alpha * col.astype(np.float32), where=m[y : y + bh, x : x + bw, None] != 0)
    out = np.rint(img).astype(np.uint8)
    for m, col in zip(small, colors):
        _outline(out, m, tuple(int(c) for c in col))
    if target is not None:
        _outline(out, resize_mask(_mask(target, "target mask"), size), TARGET_RGB)
    return out


# -- sheets ----------------------------------------------------------------------

def encode_png(image) -> bytes:
    """PNG bytes of an RGB (or gray) image (:mod:`.png`: "up" row filter, ISA-L deflate; no metadata)."""
    return png.encode(as_rgb8(image, "PNG image"))


def balanced_columns(n: int, max_columns: int = 5) -> int:
    """Columns for ``n`` panels: the fewest rows of at most ``max_columns``, filled evenly,
    so no row holds a lone panel (9 panels: 5 + 4, not 4 + 4 + 1)."""
    n, max_columns = max(1, int(n)), max(1, int(max_columns))
    rows = -(-n // max_columns)
    return -(-n // rows)


#: (colour, meaning) of every colour a view's panels use; :func:`legend_items` picks those shown.
LEGEND = {
    "target": (TARGET_RGB, "green outline: target mask M"),
    "changed_in": (CHANGED_IN_TARGET_RGB, "yellow: in M, depth changed (counted by acc_depth)"),
    "missed": (MISSED_IN_TARGET_RGB, "dark red: in M, depth unchanged (missed)"),
    "no_depth": (NO_DEPTH_IN_TARGET_RGB, "blue: in M, no depth after removal (see-through hole, missed)"),
    "changed_out": (CHANGED_OUTSIDE_RGB, "light grey: outside M, depth changed"),
    "unchanged": (BACKGROUND_RGB, "dark grey: outside M, unchanged"),
    "threshold": (THRESHOLD_RGB, "cyan tick: GHT threshold t_depth on the |dD| scale"),
    "semantic": (SEMANTIC_RGB, "magenta: semantic probe's prediction"),
    "structural": (None, "random colours: structural probe masks"),
}


def legend_items(panels: Sequence[tuple[str, np.ndarray]]) -> list[tuple[tuple[int, int, int] | None, str]]:
    """The legend entries that apply to ``panels`` (by their titles, as :func:`view_panels` names them)."""
    titles = " ".join(t for t, _ in panels)
    keys = ["target"]
    if "|dD|" in titles and "t_depth" in titles:
        keys.append("threshold")
    if "changed" in titles:
        keys += ["changed_in", "missed"] + (["no_depth"] if "no depth" in titles else []) + ["changed_out", "unchanged"]
    if "semantic probe" in titles:
        keys.append("semantic")
    if any(t.split(" on ")[0] not in ("semantic probe",) and " on I_" in t for t, _ in panels):
        keys.append("structural")
    return [LEGEND[k] for k in keys]


def _legend_rows(items, width: int, scale: float = 0.38) -> list[list[tuple[tuple | None, str, int]]]:
    """Legend entries packed into lines of at most ``width`` px: [(colour, text, entry width)]."""
    rows: list[list] = [[]]
    used = 0
    for rgb, text in items:
        w = 16 + cv2.getTextSize(_ascii(text), _FONT, scale, 1)[0][0] + 14
        if rows[-1] and used + w > width:
            rows.append([])
            used = 0
        rows[-1].append((rgb, text, w))
        used += w
    return rows if rows[0] else []


def _draw_legend(sheet: np.ndarray, rows, y: int, scale: float = 0.38) -> None:
    for r in rows:
        x = _PAD
        for rgb, text, w in r:
            if rgb is None:  # several random colours
                for k, col in enumerate(mask_colors(3, seed=1)):
                    cv2.rectangle(sheet, (x + 4 * k, y + 3), (x + 4 * k + 3, y + 13), tuple(int(c) for c in col), -1)
            else:
                cv2.rectangle(sheet, (x, y + 3), (x + 11, y + 13), tuple(int(c) for c in rgb), -1)
                cv2.rectangle(sheet, (x, y + 3), (x + 11, y + 13), (90, 90, 90), 1)
            _put_text(sheet, text, (x + 16, y + 13), scale=scale)
            x += w
        y += _TITLE_H


def sheet_image(panels: Sequence[tuple[str, np.ndarray]], *, columns: int | None = None,
                panel_width: int = PANEL_WIDTH, title: str | None = None, lines: Sequence[str] = (),
                legend: Sequence[tuple[tuple[int, int, int] | None, str]] = ()) -> np.ndarray:
    """Titled panels on a white grid, as uint8 (H, W, 3) RGB.

    panels: (title, image) pairs; images of any size / kind accepted by
        :func:`as_rgb8`, each resized to ``panel_width``.
    columns: panels per row (default :func:`balanced_columns`).  title:
    optional line above the grid; lines: text lines under it (e.g. the
    view's numbers); legend: (colour or None, meaning) entries drawn under
    the grid.
    """
    if not panels:
        raise InputError("a contact sheet needs at least one panel")
    width = _check_width(panel_width)
    cols = balanced_columns(len(panels)) if columns is None else max(1, min(int(columns), len(panels)))
    imgs = [(t, rgb8_at(p, width, f"panel {t!r}")) for t, p in panels]
    rows = [imgs[i : i + cols] for i in range(0, len(imgs), cols)]
    row_h = [_TITLE_H + max(im.shape[0] for _, im in r) for r in rows]
    sheet_w = _PAD + cols * (width + _PAD)
    head = (_TITLE_H + 4 if title else 0) + _TITLE_H * len(lines)
    legend_rows = _legend_rows(legend, sheet_w - 2 * _PAD)
    foot = _TITLE_H * len(legend_rows) + (_PAD if legend_rows else 0)
    sheet_h = head + _PAD + sum(h + _PAD for h in row_h) + foot
    sheet = np.full((sheet_h, sheet_w, 3), 255, np.uint8)
    y = 0
    if title:
        _put_text(sheet, title, (_PAD, _TITLE_H - 2), scale=0.5, max_width=sheet_w - 2 * _PAD)
        y = _TITLE_H + 4
    for line in lines:
        _put_text(sheet, line, (_PAD, y + _TITLE_H - 5), rgb=(20, 20, 90), max_width=sheet_w - 2 * _PAD)
        y += _TITLE_H
    y = head + _PAD
    for r, h in zip(rows, row_h):
        for i, (t, im) in enumerate(r):
            x = _PAD + i * (width + _PAD)
            _put_text(sheet, t, (x + 1, y + _TITLE_H - 5), max_width=width - 2)
            sheet[y + _TITLE_H : y + _TITLE_H + im.shape[0], x : x + width] = im
        y += h + _PAD
    _draw_legend(sheet, legend_rows, y)
    return sheet


def contact_sheet(path: str | os.PathLike, panels: Sequence[tuple[str, np.ndarray]], *, columns: int | None = None,
                  panel_width: int = PANEL_WIDTH, title: str | None = None, lines: Sequence[str] = (),
                  legend: Sequence = (), embed_cache: str | os.PathLike | None = None) -> Path:
    """Write :func:`sheet_image` of ``panels`` as a PNG (atomically); returns the path.

    embed_cache: a folder where the JPEG report.html embeds the sheet as is
    made now, from the sheet in memory (see :mod:`.embed`)."""
    path = Path(path)
    sheet = sheet_image(panels, columns=columns, panel_width=panel_width, title=title, lines=lines, legend=legend)
    data = png.encode(sheet)
    write_bytes(path, data, sync=False)  # regenerated if damaged
    if embed_cache is not None:
        from .embed import embed_jpeg, store_embed

        # what decoding the (lossless) PNG would give, without decoding it
        jpeg = embed_jpeg(cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
        if jpeg is not None:
            store_embed(embed_cache, data, jpeg)
    return path


def _panel_columns(sheet: np.ndarray, y0: int) -> tuple[int, int] | None:
    """(columns, panel width) of a :func:`sheet_image` sheet whose first panel row starts at ``y0``:
    the most columns whose gaps are white over the first 16 rows of the panels."""
    h, w = sheet.shape[:2]
    band = sheet[y0 : y0 + 16]
    if band.shape[0] < 16:
        return None
    for cols in range(12, 1, -1):
        pw, rem = divmod(w - _PAD, cols)
        pw -= _PAD
        if rem or pw < 16:
            continue
        gaps = [k * (pw + _PAD) for k in range(1, cols)]  # x of the gap before panel k (_PAD wide)
        if all((band[:, x : x + _PAD] >= 255).all() and not (band[:, x - 1] >= 255).all() for x in gaps):
            return cols, pw
    return None


def sheet_panel(sheet: np.ndarray, index: int, *, n_lines: int, title: bool = True) -> np.ndarray | None:
    """Panel ``index`` of the first row of a sheet written by :func:`sheet_image` (``n_lines``
    text lines under the title), or None when the sheet does not have that layout.

    The panel width is found from the white gaps between the panels; the panel's height is
    where its column turns white (the gap before the next row)."""
    y0 = (_TITLE_H + 4 if title else 0) + _TITLE_H * n_lines + _PAD + _TITLE_H
    found = _panel_columns(sheet, y0)
    if found is None or index >= found[0]:
        return None
    panel_width = found[1]
    x0 = _PAD + index * (panel_width + _PAD)
    block = sheet[y0:, x0 : x0 + panel_width]
    white = np.flatnonzero((block >= 255).all(axis=(1, 2)))
    end = int(white[0]) if white.size else block.shape[0]
    return block[:end].copy() if end >= 16 else None


def _num(x, decimals: int) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "--"
    if v != v:
        return "--"
    if v in (float("inf"), float("-inf")):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{decimals}f}"


def view_numbers(record: dict | None, xi: float = XI_DEFAULT) -> list[str]:
    """One view's numbers as short ASCII lines (per semantic / structural probe, the geometric axis,
    fidelity), from a view record (:meth:`r360gpu.metrics.record.ViewRecord.to_dict`)."""
    if not record:
        return []
    sem_parts, rest = [], []
    for p, v in (record.get("semantic") or {}).items():
        if v.get("empty_target"):
            sem_parts.append(f"{p}: empty target (excluded)")
            continue
        post = v.get("iou_post")
        found = "found" if isinstance(post, (int, float)) and post >= xi else "not found"
        sem_parts.append(f"{p}: IoU {_num(v.get('iou_pre'), 2)} -> {_num(post, 2)} ({found} at xi={xi:g})")
    geo = record.get("geometric") or {}
    if geo:
        if geo.get("excluded"):
            rest.append("acc_depth excluded")
        else:
            rest.append(f"acc_depth {_num(geo.get('acc_depth'), 3)} (t_depth {_num(geo.get('threshold'), 3)})")
    for p, v in (record.get("structural") or {}).items():
        rest.append(f"sim_SAM {_num(v.get('sim_sam'), 3)} [{p}]")
    fid = record.get("fidelity") or {}
    if fid:
        f = f"PSNR {_num(fid.get('psnr'), 1)} dB, SSIM {_num(fid.get('ssim'), 3)}"
        if fid.get("lpips") is not None:
            f += f", LPIPS {_num(fid.get('lpips'), 3)}"
        rest.append(f)
    lines = ["semantic: " + "; ".join(sem_parts)] if sem_parts else []
    if rest:
        lines.append(" | ".join(rest))
    return lines


@dataclass
class SheetView:
    """What one view's panels are drawn from (:func:`view_panels`).

    pre, post, ref: RGB renderings I_pre, I_post, I_ref (ref optional).
    target: (H, W) target mask M (outlined in green on every panel but the heat map).
    delta, threshold: |dD| and the GHT threshold t_depth in the same units for the heat map
        (skipped when delta is None).  In compat mode pass the 8-bit
        normalised |dD| and the gray-level threshold.
    changed: (H, W) bool changed mask; pass ``GeometricView.changed`` to show
        exactly the pixels acc_depth counted; default ``delta > threshold``
        when both are given.
    no_depth: (H, W) bool, no depth after removal (D_post missing); its pixels
        in M are drawn in their own colour and counted in the panel's title.
    semantic_post, semantic_pre: the semantic probe's predicted (union) masks
        on I_post / I_pre, drawn in magenta (skipped when None).
    structural: (title, rgb, masks) per structural panel, e.g.
        ("SAM masks on I_post", post, masks_a); masks in random colours.
    """

    pre: object
    post: object
    target: object
    ref: object = None
    delta: object = None
    threshold: float | None = None
    changed: object = None
    no_depth: object = None
    semantic_post: object = None
    semantic_pre: object = None
    structural: Sequence[tuple[str, object, object]] = ()


def view_panels(view: SheetView, *, width: int = PANEL_WIDTH, seed: int = 0,
                memo: ByIdentity | None = None) -> list[tuple[str, np.ndarray]]:
    """The standard panels of ``view`` (a :class:`SheetView`), in the report's order.

    memo: a :class:`~r360gpu.util.memo.ByIdentity` shared by the sheets of one
    view's methods: a panel made from the same array objects (I_pre, I_ref
    and the probes' readings on them) is made once and reused, not drawn
    again for every method.
    """
    pre, post, target, ref, delta, threshold = view.pre, view.post, view.target, view.ref, view.delta, view.threshold
    changed, no_depth, semantic_post, semantic_pre, structural = (view.changed, view.no_depth, view.semantic_post,
                                                                  view.semantic_pre, view.structural)

    def once(name, arrays, make):
        return make() if memo is None else memo.get((name, width, seed), arrays, make)

    out = [("I_pre (target outlined)", once("rgb", (pre, target), lambda: rgb_panel(pre, width, target=target))),
           ("I_post (target outlined)", once("rgb", (post, target), lambda: rgb_panel(post, width, target=target)))]
    if ref is not None:
        out.append(("I_ref", once("rgb", (ref, target), lambda: rgb_panel(ref, width, target=target))))
    if delta is not None:
        label = "|dD|" if threshold is None else f"|dD|, t_depth (GHT) = {float(threshold):.3g}"
        out.append((label, depth_change_panel(delta, threshold, width)))
        if changed is None and threshold is not None:
            changed = np.abs(np.nan_to_num(np.asarray(delta, np.float64))) > float(threshold)
    if changed is not None:
        title = "changed |dD| > t_depth (legend below)"
        hole = None if no_depth is None else no_depth_fraction(no_depth, target)
        if hole:  # the share of M, so the figure does not depend on the panel's size
            title = f"changed |dD| > t_depth; no depth in {hole:.0%} of M (legend below)"
        out.append((title, changed_panel(changed, target, width, no_depth=no_depth)))
    if semantic_pre is not None:
        out.append(("semantic probe on I_pre",
                    once("semantic", (pre, semantic_pre, target),
                         lambda: mask_overlay(pre, semantic_pre, width, color=SEMANTIC_RGB, target=target))))
    if semantic_post is not None:
        out.append(("semantic probe on I_post",
                    once("semantic", (post, semantic_post, target),
                         lambda: mask_overlay(post, semantic_post, width, color=SEMANTIC_RGB, target=target))))
    for i, (t, rgb, masks) in enumerate(structural):
        out.append((t, once(f"structural {i}", (rgb, masks, target),
                            lambda rgb=rgb, masks=masks, i=i: mask_overlay(rgb, masks, width, target=target,
                                                                            seed=seed + i))))
    return out


def view_contact_sheet(path: str | os.PathLike, *, title: str | None = None, columns: int | None = None,
                       width: int = PANEL_WIDTH, record: dict | None = None,
                       embed_cache: str | os.PathLike | None = None, seed: int = 0, memo: ByIdentity | None = None,
                       **panels) -> Path:
    """Write the contact sheet of one view (panels from :func:`view_panels`: ``panels`` are the
    :class:`SheetView` fields) with the view's numbers from ``record`` (a view record dict; see
    :func:`view_numbers`) under the title and the colour legend at the bottom; returns the path.
    embed_cache: as in :func:`contact_sheet`."""
    ps = view_panels(SheetView(**panels), width=width, seed=seed, memo=memo)
    return contact_sheet(path, ps, columns=columns, panel_width=width, title=title, lines=view_numbers(record),
                         legend=legend_items(ps), embed_cache=embed_cache)
