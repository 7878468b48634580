"""viewer.docking: the panels are docked beside the pictures, never over them."""
from __future__ import annotations

import pytest

from r360gpu.viewer.compose import layout
from r360gpu.viewer.docking import MIN_VIEW, dock


def _overlap(a, b) -> bool:
    ax, ay, aw, ah = a
    bx, by, bw, bh = b
    return ax < bx + bw and bx < ax + aw and ay < by + bh and by < ay + ah


@pytest.mark.parametrize("fb", [(900, 560), (1280, 720), (1920, 1080), (700, 1200), (500, 400)])
@pytest.mark.parametrize("mode", ["none", "side", "wipe"])
@pytest.mark.parametrize("aspect", [4 / 3, 16 / 9, 0.75, None])
def test_no_panel_covers_a_picture(fb, mode, aspect):
    d = dock(*fb, show=True, left_w=330, metrics_w=380, metrics_h=270, mode=mode, aspect=aspect)
    x, y, w, h = d.view
    lay = layout(mode, w, h, aspect=aspect, x0=x, y0=y)
    for rect in lay.rects:
        assert rect[0] >= 0 and rect[1] >= 0 and rect[0] + rect[2] <= fb[0] and rect[1] + rect[3] <= fb[1]
        for panel in (d.controls, d.metrics):
            if panel is not None:
                assert not _overlap(rect, panel), (rect, panel)


def test_metrics_goes_where_the_pictures_are_larger():
    # side by side of wide pictures: room below, not at the right
    side = dock(1280, 720, show=True, left_w=330, metrics_w=380, metrics_h=270, mode="side", aspect=4 / 3)
    assert side.metrics_side == "bottom" and side.metrics == (330, 450, 950, 270)
    # one tall picture: room at the right
    tall = dock(1280, 720, show=True, left_w=330, metrics_w=380, metrics_h=270, mode="none", aspect=0.75)
    assert tall.metrics_side == "right" and tall.view == (330, 0, 570, 720)
    # too small for a Metrics dock: left out (its contents go into the left panel)
    small = dock(600, 300, show=True, left_w=330, metrics_w=380, metrics_h=270, mode="none")
    assert small.metrics is None and small.view == (300, 0, 300, 300)
    assert 600 - 300 - 380 < MIN_VIEW and 300 - 270 < MIN_VIEW


def test_hidden_panels_give_the_whole_window():
    d = dock(900, 560, show=False, left_w=330, metrics_w=380, metrics_h=270, mode="side", aspect=4 / 3)
    assert d.view == (0, 0, 900, 560) and d.controls is None and d.metrics is None
