"""Window layout and composition: single view, side by side, A/B wipe.

:func:`layout` decides where the pictures go (pure arithmetic, tested);
:class:`Compositor` draws them with ``shaders/viewer_compose.wgsl`` into any
render target (the window's texture, or an offscreen texture for
screenshots).  Rectangles are (x0, y0, width, height) in framebuffer pixels,
origin top left.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from r360gpu.gpu.context import GpuContext

SHADER = "viewer_compose"
MODES = {"none": 0, "side": 1, "wipe": 2}
LETTERBOX = (0.08, 0.08, 0.09)
#: Framebuffer pixels around the wipe line that grab it for dragging.
WIPE_GRAB_PX = 8.0


def fit_rect(region: tuple[float, float, float, float], aspect: float | None) -> tuple[int, int, int, int]:
    """The largest rectangle of width/height ``aspect`` centred in ``region`` (integer pixels).

    ``aspect`` None fills the region.
    """
    x, y, w, h = region
    if aspect is None or w <= 0 or h <= 0:
        return int(round(x)), int(round(y)), max(1, int(round(w))), max(1, int(round(h)))
    if w / h > aspect:
        fw, fh = h * aspect, h
    else:
        fw, fh = w, w / aspect
    fw, fh = max(1, int(round(fw))), max(1, int(round(fh)))
    return int(round(x + (w - fw) / 2)), int(round(y + (h - fh) / 2)), fw, fh


@dataclass(frozen=True)
class Layout:
    """Where the pictures go: ``rects[i]`` is picture i's rectangle; ``regions`` the panel areas.

    wipe_x: the wipe line's x in framebuffer pixels (wipe mode), else None.
    """

    mode: str
    regions: tuple
    rects: tuple
    wipe_x: float | None = None

    def render_size(self, scale: float = 1.0) -> tuple[int, int]:
        """Pixels to render per picture at linear ``scale`` (at least 8 x 8)."""
        _, _, w, h = self.rects[0]
        return max(8, int(round(w * scale))), max(8, int(round(h * scale)))


def layout(mode: str, width: int, height: int, *, aspect: float | None = None, wipe: float = 0.5,
           x0: int = 0, y0: int = 0) -> Layout:
    """Picture rectangles for ``mode`` in the ``width x height`` area at (x0, y0) of the framebuffer.

    side: the area split into left / right halves, each picture fitted to
    its half.  none / wipe: one picture fitted to the area.  ``aspect``:
    the width / height the pictures must keep (None: fill).  ``wipe``: the
    wipe line as a fraction of the picture's width.
    """
    if mode not in MODES:
        raise ValueError(f"compare mode must be one of {tuple(MODES)}, got {mode!r}")
    width, height = max(2, int(width)), max(1, int(height))
    if mode == "side":
        half = width // 2
        regions = ((x0, y0, half, height), (x0 + half, y0, width - half, height))
        a = aspect if aspect is not None else half / max(1, height)
        rects = tuple(fit_rect(r, a) for r in regions)
        # Both pictures must have the same size (one camera renders both).
        w = min(rects[0][2], rects[1][2])
        h = min(rects[0][3], rects[1][3])
        rects = tuple(fit_rect(r, w / h) if (r[2], r[3]) != (w, h) else r for r in rects)
        rects = tuple((x + (rw - w) // 2, y + (rh - h) // 2, w, h) for x, y, rw, rh in rects)
        return Layout(mode, regions, rects)
    region = (x0, y0, width, height)
    rect = fit_rect(region, aspect)
    wipe_x = rect[0] + float(min(1.0, max(0.0, wipe))) * rect[2] if mode == "wipe" else None
    return Layout(mode, (region,), (rect,) if mode == "none" else (rect, rect), wipe_x)


def wipe_fraction(x: float, lay: Layout) -> float:
    """The wipe fraction that puts the line at framebuffer x."""
    rx, _, rw, _ = lay.rects[0]
    return float(min(1.0, max(0.0, (x - rx) / max(1, rw))))


def picture_at(lay: Layout, x: float, y: float) -> int | None:
    """Index of the picture under framebuffer point (x, y), None outside all."""
    for i, (rx, ry, rw, rh) in enumerate(lay.rects):
        if rx <= x < rx + rw and ry <= y < ry + rh:
            if lay.mode == "wipe":
                return 0 if x < lay.wipe_x else 1
            return i
    return None


class Compositor:
    """Draws packed-rgba8 pictures into a texture view with the compose shader."""

    def __init__(self, ctx: GpuContext):
        self.ctx = ctx
        self._pipelines: dict[str, object] = {}
        self._dummy = ctx.buffer(np.zeros(4, np.uint32), label="viewer.compose.dummy")

    def pipeline(self, fmt: str):
        pipe = self._pipelines.get(fmt)
        if pipe is None:
            module = self.ctx.shader(SHADER)
            pipe = self.ctx.device.create_render_pipeline(
                label=f"{SHADER}:{fmt}",
                layout="auto",
                vertex={"module": module, "entry_point": "vs_main", "buffers": []},
                primitive={"topology": "triangle-list"},
                fragment={"module": module, "entry_point": "fs_main", "targets": [{"format": fmt}]},
            )
            self._pipelines[fmt] = pipe
        return pipe

    def record(self, enc, target_view, fmt: str, lay: Layout, pictures: list[tuple[object, int, int] | None]) -> None:
        """Record the composition of ``pictures`` ((buffer, width, height) or None) into ``target_view``.

        A missing picture (None) leaves its rectangle in the letterbox colour.
        """
        words = np.zeros(20, np.uint32)
        f32 = words.view(np.float32)
        rects = list(lay.rects) + [lay.rects[-1]] * (2 - len(lay.rects))
        pics = list(pictures) + [None] * (2 - len(pictures))
        mode = MODES[lay.mode]
        for k, (rect, pic) in enumerate(zip(rects, pics)):
            f32[4 * k: 4 * k + 4] = rect
            # Size 0 marks a missing picture: the shader draws the letterbox colour there.
            words[8 + 2 * k: 10 + 2 * k] = (pic[1], pic[2]) if pic is not None else (0, 0)
        words[12] = mode
        words[13] = 1 if fmt.endswith("-srgb") else 0
        f32[14] = lay.wipe_x if lay.wipe_x is not None else -1.0
        f32[16:19] = LETTERBOX
        f32[19] = 1.0
        params = self.ctx.buffer(words, usage=0x40 | 0x08, label="viewer.compose.params")
        pipe = self.pipeline(fmt)
        a = pics[0][0] if pics[0] is not None else self._dummy
        b = pics[1][0] if pics[1] is not None else a
        bind = self.ctx.device.create_bind_group(
            layout=pipe.get_bind_group_layout(0),
            entries=[{"binding": 0, "resource": {"buffer": params, "offset": 0, "size": params.size}},
                     {"binding": 1, "resource": {"buffer": a, "offset": 0, "size": a.size}},
                     {"binding": 2, "resource": {"buffer": b, "offset": 0, "size": b.size}}],
        )
        rp = enc.begin_render_pass(color_attachments=[{
            "view": target_view, "clear_value": (*LETTERBOX, 1.0), "load_op": "clear", "store_op": "store"}])
        rp.set_pipeline(pipe)
        rp.set_bind_group(0, bind)
        rp.draw(3, 1, 0, 0)
        rp.end()
