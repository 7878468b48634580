"""One frame of the viewer, start to end.

:meth:`FrameLoop.frame`: apply held movement keys (or the next camera of a
fly-through) -> note whether the camera moved -> dock the panels beside the
pictures (:mod:`r360gpu.viewer.docking`) and lay the pictures out
(:mod:`r360gpu.viewer.compose`) -> pick the render scale (progressive: reduced while
the camera moves, full once it rests, :mod:`r360gpu.viewer.quality`) -> render and
overlay each shown scene (:mod:`r360gpu.viewer.frame_pictures`) -> measure the live axis
once the camera rests (:mod:`r360gpu.viewer.live`) -> compose into the window ->
view captures -> imgui panels and pane labels (:mod:`r360gpu.viewer.panels`) ->
window captures (:mod:`r360gpu.viewer.capture`).
"""
from __future__ import annotations

from .compose import layout
from .docking import Docks, dock


class FrameLoop:
    """The frame function of one :class:`r360gpu.viewer.app.ViewerApp` and what the last frame did.

    last_layout, last_camera, last_scale, docks: the last frame's layout,
    render camera, render scale and panel docks; frames: frames drawn;
    frame_seconds: the last frame's duration; pictures: its pictures.
    """

    def __init__(self, app):
        self.app = app
        now = app.clock()
        self.last_frame = now
        self.last_motion = now
        self.pose_key = None
        self.last_layout = None
        self.last_camera = None
        self.last_scale = 1.0
        self.docks: Docks | None = None
        self.frames = 0
        self.frame_seconds = 0.0
        self.busy = True

    def teleported(self) -> None:
        """The camera jumped (not a continuous move): draw the next frame at full resolution."""
        app = self.app
        self.pose_key = app.camera.pose_key()
        self.last_motion = app.clock() - app.policy.still_delay

    def dock(self, view: str | None) -> Docks:
        """Where the panels and the pictures go this frame."""
        app = self.app
        fb_w, fb_h = app.framebuffer_size()
        gui = app.gui
        ratio = float(app.canvas.get_pixel_ratio() or 1.0)
        show = gui is not None and app.state.show_ui
        sizes = gui.dock_sizes() if gui is not None else (0.0, 0.0, 0.0)
        left, mw, mh = (int(round(v * ratio)) for v in sizes)
        return dock(fb_w, fb_h, show=show, left_w=left, metrics_w=mw, metrics_h=mh, mode=app.state.compare,
                    aspect=app.pictures.aspect(view))

    def _move_camera(self, now: float) -> None:
        app = self.app
        dt = min(0.1, max(0.0, now - self.last_frame))
        self.last_frame = now
        s = app.state
        if app.camera.mode != s.camera_mode:
            app.camera.set_mode(s.camera_mode)
        f, r, u = s.movement()
        if (f or r or u) and app.can_move:
            app.camera.move(f, r, u, dt, app.input.modifiers)
        cam = app.captures.next_flight_camera()
        if cam is not None:
            app.camera.set_camera(cam)
            app.state = app.state.moved()  # between evaluation views: no view's mask applies
        key = app.camera.pose_key()
        if key != self.pose_key:
            self.pose_key = key
            self.last_motion = now
            app.meter.stale = bool(app.meter.live)
        if app.can_move and app.camera.snapped is None:
            app.state = app.state.moved()

    def frame(self) -> None:
        """Draw one frame into the canvas (the canvas' draw function)."""
        app = self.app
        t_start = now = app.clock()
        self._move_camera(now)
        view = app.current_view()
        self.docks = self.dock(view)
        x0, y0, area_w, area_h = self.docks.view
        lay = layout(app.state.compare, area_w, area_h, aspect=app.pictures.aspect(view), wipe=app.state.wipe,
                     x0=x0, y0=y0)
        self.last_layout = lay
        since = now - self.last_motion
        full_w, full_h = lay.render_size(1.0)
        scale = app.policy.quantised(app.policy.scale(since, full_w * full_h * len(app.pictures.involved())))
        if app.captures.recorder is not None:
            scale = 1.0  # recordings are written at full resolution
        rw, rh = app.pictures.render_size(lay, scale, view)
        cam = app.camera.render_camera(rw, rh)
        self.last_camera, self.last_scale = cam, scale
        pictures = app.pictures.render(cam, view, lay)
        if scale >= 1.0 and since >= app.policy.still_delay:
            app.meter.update(cam, view)
        texture = app.canvas_context.get_current_texture()
        enc = app.ctx.encoder()
        app.compositor.record(enc, texture.create_view(), app.format, lay, pictures)
        app.ctx.submit(enc)
        app.captures.after_pictures(lay, pictures, cam)
        if app.gui is not None:
            app.gui.render()
        app.captures.after_panels(texture)
        self.frames += 1
        self.frame_seconds = app.clock() - t_start
        if app.captures.flight_done:
            app.captures.flight_done = False
            app.captures.set_recording(False)
        cap = app.captures
        self.busy = (any(app.state.movement()) or app.input.drag is not None or scale < 1.0 or bool(cap.flight)
                     or app.state.recording or bool(cap.pending) or since < app.policy.still_delay)
        if self.busy:
            app.request_draw()
