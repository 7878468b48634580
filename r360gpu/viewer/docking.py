"""Where the panels go, so that they never cover a scene pane (pure arithmetic, tested).

The controls are docked at the window's left edge.  The Metrics panel is
docked either at the right edge or along the bottom, whichever leaves the
larger pictures for the comparison mode and picture aspect at hand (side by
side with wide pictures leaves room below; a single tall picture leaves room
at the right).  The pictures are laid out in what is left
(:func:`r360gpu.viewer.compose.layout`).  Rectangles are (x0, y0, width, height) in
framebuffer pixels.
"""
from __future__ import annotations

from dataclasses import dataclass

from .compose import layout

#: Smallest picture area (framebuffer px) kept free of panels on each axis.
MIN_VIEW = 160


@dataclass(frozen=True)
class Docks:
    """view: the area left to the pictures; controls: the left panel's rectangle (None when
    hidden); metrics: the Metrics panel's rectangle (None when hidden); metrics_side: "right",
    "bottom" or ""."""

    view: tuple[int, int, int, int]
    controls: tuple[int, int, int, int] | None
    metrics: tuple[int, int, int, int] | None
    metrics_side: str = ""


def _picture_area(mode: str, area: tuple[int, int, int, int], aspect: float | None) -> int:
    x, y, w, h = area
    if w < 2 or h < 1:
        return 0
    lay = layout(mode, w, h, aspect=aspect, x0=x, y0=y)
    return sum(r[2] * r[3] for r in lay.rects[: 2 if mode == "side" else 1])


def dock(fb_w: int, fb_h: int, *, show: bool, left_w: int, metrics_w: int, metrics_h: int,
         mode: str = "none", aspect: float | None = None) -> Docks:
    """The docks for a ``fb_w x fb_h`` framebuffer (panel sizes in framebuffer px).

    show False: no panels, the pictures get the whole window.  The left
    panel takes at most half the width; the Metrics panel goes right or
    bottom, whichever gives the larger pictures (ties: right), and is left
    out when neither leaves :data:`MIN_VIEW` px for the pictures.
    """
    fb_w, fb_h = max(1, int(fb_w)), max(1, int(fb_h))
    if not show:
        return Docks((0, 0, fb_w, fb_h), None, None)
    lw = min(fb_w // 2, max(0, int(left_w)))
    controls = (0, 0, lw, fb_h)
    rest_w = fb_w - lw
    options = []
    mw, mh = int(metrics_w), int(metrics_h)
    if rest_w - mw >= MIN_VIEW:
        options.append(("right", (lw, 0, rest_w - mw, fb_h), (fb_w - mw, 0, mw, fb_h)))
    if fb_h - mh >= MIN_VIEW:
        options.append(("bottom", (lw, 0, rest_w, fb_h - mh), (lw, fb_h - mh, rest_w, mh)))
    if not options:
        return Docks((lw, 0, rest_w, fb_h), controls, None)
    side, view, metrics = max(options, key=lambda o: _picture_area(mode, o[1], aspect))
    return Docks(view, controls, metrics, side)
