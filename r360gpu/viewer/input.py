"""Keyboard and pointer input of the viewer: events -> state machine -> app actions.

:class:`Input` turns rendercanvas events into :func:`r360gpu.viewer.state.handle_key`
transitions and camera moves, and carries out the state machine's
:class:`~r360gpu.viewer.state.Action` requests on the app (camera jumps, captures,
closing the window).
"""
from __future__ import annotations

import numpy as np

from .compose import WIPE_GRAB_PX, wipe_fraction
from .state import Action, handle_key


class Input:
    """Input handling of one :class:`r360gpu.viewer.app.ViewerApp`.

    modifiers: the modifier keys of the last event; drag: (kind, x, y) of
    the mouse drag under way ("turn", "pan" or "wipe"), or None.
    """

    def __init__(self, app):
        self.app = app
        self.modifiers: tuple = ()
        self.drag = None

    def key(self, key: str, modifiers=(), down: bool = True) -> None:
        """Feed one key event through the state machine and carry out its actions."""
        app = self.app
        self.modifiers = tuple(modifiers)
        was = app.state.overlays.residuals
        app.state, actions = handle_key(app.state, key, modifiers, down=down)
        for a in actions:
            self.apply(a)
        if app.state.overlays.residuals and not was:  # key O: say when no shown scene has residuals
            shown = app.state.shown()
            if not any(app.residuals.available(n) for n in shown):
                app.notify(f"no residuals for {', '.join(shown)}: score with --residuals and open the viewer "
                           f"with --results (or open a residuals/SCENE/METHOD.ply as the method)")
        app.request_draw()

    def apply(self, action: Action) -> None:
        """Carry out one :class:`Action` of the state machine."""
        app = self.app
        k, arg = action.kind, action.arg
        if k == "view":
            app.jump_to_view(int(arg))
        elif k == "snap":
            app.snap()
        elif k == "worst":
            app.jump_to_worst_view()
        elif k == "reset":
            app.camera.reset()
            app.teleported()
        elif k == "focus":
            app.target.focus()
            app.teleported()
        elif k == "fov":
            app.camera.set_fov(app.camera.fov_y + float(arg))
        elif k == "up":
            app.camera.cycle_up(app.cameras)
            app.notify(f"world up axis: {app.camera.up_choice} {np.round(app.camera.up, 3).tolist()}")
        elif k == "level":
            app.camera.level()
        elif k == "screenshot":
            app.captures.request_screenshot(str(arg))
        elif k == "record":
            app.captures.set_recording(bool(arg))
        elif k == "quit":
            app.quit()
        else:
            raise ValueError(f"unknown action {k!r}")

    def on_event(self, ev: dict) -> None:
        """rendercanvas event handler (keys, pointer, wheel)."""
        app = self.app
        t = ev["event_type"]
        if t in ("key_down", "key_up"):
            self.key(ev["key"], ev.get("modifiers", ()), down=t == "key_down")
            return
        ratio = float(app.canvas.get_pixel_ratio() or 1.0)
        x, y = ev.get("x", 0.0) * ratio, ev.get("y", 0.0) * ratio
        lay = app.last_layout
        if t == "pointer_down":
            self.modifiers = tuple(ev.get("modifiers", ()))
            button = ev.get("button", 1)
            if (button == 1 and lay is not None and lay.mode == "wipe" and lay.wipe_x is not None
                    and abs(x - lay.wipe_x) <= WIPE_GRAB_PX):
                self.drag = ("wipe", x, y)
            elif button == 1 and "Shift" not in self.modifiers:
                self.drag = ("turn", x, y)
            else:
                self.drag = ("pan", x, y)
        elif t == "pointer_move" and self.drag is not None:
            kind, x0, y0 = self.drag
            dx, dy = x - x0, y - y0
            self.drag = (kind, x, y)
            if kind == "wipe" and lay is not None:
                app.state = app.state.with_wipe(wipe_fraction(x, lay))
            elif app.can_move and kind == "turn":
                app.camera.drag(dx, dy)
            elif app.can_move and kind == "pan":
                h = lay.rects[0][3] if lay else app.framebuffer_size()[1]
                app.camera.pan(dx, dy, h)
        elif t == "pointer_up":
            self.drag = None
        elif t == "wheel" and app.can_move:
            app.camera.zoom(-float(ev.get("dy", 0.0)) / 100.0)
        app.request_draw()
