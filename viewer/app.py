"""The viewer application: a rendercanvas canvas, r360gpu's renderer, overlays, composition and imgui.

:class:`ViewerApp` owns everything and draws one frame per :meth:`frame`
call; any rendercanvas canvas works (glfw for the desktop app, the offscreen
canvas for headless tests).  One wgpu device is shared by the canvas, imgui
and r360gpu: the app configures the canvas with the device of its
:class:`~r360gpu.gpu.GpuContext`.

A frame: apply held movement keys -> pick the render scale (progressive:
reduced while the camera moves, full once it rests, see
:mod:`viewer.quality`) -> render each shown scene (and pre, when the |dD|
overlays need it) into device planes (:mod:`viewer.layers`; unchanged
cameras are not re-rendered) -> overlay pass per picture
(:mod:`viewer.overlays`) -> composition into the window
(:mod:`viewer.compose`) -> imgui panels (:mod:`viewer.panels`) -> captures.
When the camera has rested, the live geometric axis is measured
(:mod:`viewer.live`).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from r360gpu.gpu import get_context
from r360gpu.io.masks import load_mask

from . import capture
from .camera import CameraController, nearest_camera, scene_scale
from .compose import WIPE_GRAB_PX, Compositor, Layout, layout, wipe_fraction
from .layers import PlaneImage, SplatLayer, build_layers, camera_key
from .live import LiveAxis, delta_stats, live_axis
from .overlays import OverlayPass, OverlaySettings, resize_nearest
from .quality import ResolutionPolicy
from .state import Action, ViewerState, handle_key
from .target import Target, estimate_target, projected_mask, voting_views

#: Seconds a status message stays on screen.
MESSAGE_SECONDS = 4.0
#: Target masks kept in memory (read from disk again after that).
MASK_CACHE = 32
#: Offscreen format of view-only captures.
CAPTURE_FORMAT = "rgba8unorm"


def _texture_usage():
    import wgpu

    return wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC


class ViewerApp:
    """The viewer on ``canvas`` for ``bundle`` (:class:`r360gpu.bundle.Bundle`).

    results: optional :class:`viewer.results.SceneResults`; ctx: the
    :class:`GpuContext` (default :func:`r360gpu.gpu.get_context`); policy:
    the :class:`ResolutionPolicy`; capture_dir: where screenshots and
    recordings go; gui: draw the imgui panels; clock: time source (seconds).
    """

    def __init__(self, bundle, *, canvas, results=None, ctx=None, policy: ResolutionPolicy | None = None,
                 capture_dir: str | Path | None = None, gui: bool = True, clock=time.perf_counter):
        self.ctx = ctx or get_context()
        self.bundle = bundle
        self.results = results
        self.canvas = canvas
        self.clock = clock
        self.policy = policy or ResolutionPolicy()
        self.capture_dir = Path(capture_dir) if capture_dir is not None else Path.cwd() / "r360gpu-captures"
        self.layers = build_layers(bundle, self.ctx)
        self.views: list[str] = list(bundle.views)
        cams = bundle.cameras or {}
        self.view_cameras = [cams.get(v) for v in self.views]
        self.cameras = [c for c in self.view_cameras if c is not None]
        self.can_move = any(isinstance(l, SplatLayer) for l in self.layers.values()) and bool(self.cameras)
        self.state = ViewerState.initial(list(self.layers), len(self.views))
        self.camera = CameraController.for_cameras(self.cameras)
        self.scale_length = scene_scale(self.cameras)
        self.overlay = OverlayPass(self.ctx)
        self.compositor = Compositor(self.ctx)
        self.target: Target | None = None
        self._target_done = False
        self._target_layer: SplatLayer | None = None
        self.live: dict[str, LiveAxis] = {}
        self.live_note = ""
        self.live_stale = False  # the camera moved since the live axis was measured
        self._live_key = None
        self.messages: list[tuple[float, str]] = []
        self.modifiers: tuple = ()
        self._drag = None
        self._last_frame = clock()
        self._last_motion = clock()
        self._pose_key = None
        self._pic_buffers: list = [None, None]
        self._masks: dict = {}
        self._mask_buffers: dict = {}
        self._probe_buffers: dict = {}
        self._frame_cache: dict = {}
        self._pending_shots: list[tuple[str, Path | None]] = []
        self.recorder: capture.PathRecorder | None = None
        self._last_recorded = None
        self._flight: list = []  # cameras still to visit on a recorded fly-through
        self._flight_done = False
        self.last_layout: Layout | None = None
        self.last_camera = None
        self.last_scale = 1.0
        self.frame_seconds = 0.0
        self.frames = 0
        self.probe_choice = 0
        self.probe_found: list = []
        self.last_delta: dict = {}
        self.last_shot: Path | None = None
        self._busy = True
        self._configure_canvas()
        self.gui = None
        if gui:
            from .panels import Panels

            self.gui = Panels(self)
        canvas.add_event_handler(self.on_event, "key_down", "key_up", "pointer_down", "pointer_move",
                                 "pointer_up", "wheel")
        if self.view_cameras and self.view_cameras[0] is not None:
            self.camera.set_camera(self.view_cameras[0])
        self._teleported()

    # -- canvas -------------------------------------------------------------
    def _configure_canvas(self) -> None:
        """Configure the canvas with r360gpu's device; prefer a non-sRGB format (colours are sRGB already)."""
        cc = self.canvas.get_wgpu_context()
        preferred = cc.get_preferred_format(self.ctx.device.adapter)
        candidates = [preferred.removesuffix("-srgb"), preferred] if preferred.endswith("-srgb") else [preferred]
        self.window_copyable = True
        last = None
        for fmt in candidates:
            for usage in (_texture_usage(), None):
                try:
                    if usage is None:
                        cc.configure(device=self.ctx.device, format=fmt)
                        self.window_copyable = False
                    else:
                        cc.configure(device=self.ctx.device, format=fmt, usage=usage)
                    self.format = fmt
                    self.canvas_context = cc
                    return
                except Exception as e:  # noqa: BLE001 - an unsupported format/usage: try the next
                    last = e
        raise RuntimeError(f"cannot configure the window for rendering: {last}")

    def framebuffer_size(self) -> tuple[int, int]:
        w, h = self.canvas.get_physical_size()
        return max(1, int(w)), max(1, int(h))

    def view_area(self) -> tuple[int, int, int, int]:
        """(x0, y0, width, height) of the framebuffer left to the pictures: all of it, less the
        docked side panel while the panels are shown."""
        fb_w, fb_h = self.framebuffer_size()
        dock = 0
        if self.gui is not None and self.state.show_ui:
            dock = min(fb_w // 2, int(round(self.gui.dock_width() * float(self.canvas.get_pixel_ratio() or 1.0))))
        return dock, 0, fb_w - dock, fb_h

    def request_draw(self) -> None:
        self.canvas.request_draw()

    def notify(self, text: str) -> None:
        """Show ``text`` in the status line for a few seconds."""
        self.messages.append((self.clock(), text))
        self.messages = self.messages[-5:]

    # -- views ----------------------------------------------------------------
    def current_view(self) -> str | None:
        """The evaluation view the camera is on, or None."""
        s = self.state
        if s.on_view and s.view_index is not None:
            return self.views[s.view_index]
        return None

    def _teleported(self) -> None:
        """The camera jumped (not a continuous move): draw the next frame at full resolution."""
        self._pose_key = self.camera.pose_key()
        self._last_motion = self.clock() - self.policy.still_delay

    def jump_to_view(self, index: int) -> None:
        """Put the camera on evaluation view ``index``."""
        self.state = self.state.at_view(index)
        cam = self.view_cameras[index]
        if cam is not None:
            self.camera.set_camera(cam)
        self._teleported()

    def snap(self) -> None:
        """Jump to the evaluation camera closest to the current pose."""
        if not self.cameras:
            return
        idx = nearest_camera(self.camera.position, self.camera.rotation, self.cameras, self.scale_length)
        self.jump_to_view(self.view_cameras.index(self.cameras[idx]))

    # -- input ----------------------------------------------------------------
    def set_state(self, state: ViewerState) -> None:
        self.state = state
        self.request_draw()

    def key(self, key: str, modifiers=(), down: bool = True) -> None:
        """Feed one key event through the state machine and carry out its actions."""
        self.modifiers = tuple(modifiers)
        self.state, actions = handle_key(self.state, key, modifiers, down=down)
        for a in actions:
            self.apply(a)
        self.request_draw()

    def apply(self, action: Action) -> None:
        """Carry out one :class:`Action` of the state machine."""
        k, arg = action.kind, action.arg
        if k == "view":
            self.jump_to_view(int(arg))
        elif k == "snap":
            self.snap()
        elif k == "reset":
            self.camera.reset()
            self._teleported()
        elif k == "focus":
            self.focus_target()
            self._teleported()
        elif k == "fov":
            self.camera.set_fov(self.camera.fov_y + float(arg))
        elif k == "up":
            self.camera.cycle_up(self.cameras)
            self.notify(f"world up axis: {self.camera.up_choice} {np.round(self.camera.up, 3).tolist()}")
        elif k == "level":
            self.camera.level()
        elif k == "screenshot":
            self.request_screenshot(str(arg))
        elif k == "record":
            self.set_recording(bool(arg))
        else:
            raise ValueError(f"unknown action {k!r}")

    def on_event(self, ev: dict) -> None:
        """rendercanvas event handler (keys, pointer, wheel)."""
        t = ev["event_type"]
        if t in ("key_down", "key_up"):
            self.key(ev["key"], ev.get("modifiers", ()), down=t == "key_down")
            return
        ratio = float(self.canvas.get_pixel_ratio() or 1.0)
        x, y = ev.get("x", 0.0) * ratio, ev.get("y", 0.0) * ratio
        if t == "pointer_down":
            self.modifiers = tuple(ev.get("modifiers", ()))
            lay = self.last_layout
            button = ev.get("button", 1)
            if (button == 1 and lay is not None and lay.mode == "wipe" and lay.wipe_x is not None
                    and abs(x - lay.wipe_x) <= WIPE_GRAB_PX):
                self._drag = ("wipe", x, y)
            elif button == 1 and "Shift" not in self.modifiers:
                self._drag = ("turn", x, y)
            else:
                self._drag = ("pan", x, y)
        elif t == "pointer_move" and self._drag is not None:
            kind, x0, y0 = self._drag
            dx, dy = x - x0, y - y0
            self._drag = (kind, x, y)
            if kind == "wipe" and self.last_layout is not None:
                self.state = self.state.with_wipe(wipe_fraction(x, self.last_layout))
            elif self.can_move and kind == "turn":
                self.camera.drag(dx, dy)
            elif self.can_move and kind == "pan":
                h = self.last_layout.rects[0][3] if self.last_layout else self.framebuffer_size()[1]
                self.camera.pan(dx, dy, h)
        elif t == "pointer_up":
            self._drag = None
        elif t == "wheel" and self.can_move:
            self.camera.zoom(-float(ev.get("dy", 0.0)) / 100.0)
        self.request_draw()

    # -- target ---------------------------------------------------------------
    def ensure_target(self) -> Target | None:
        """Estimate the 3D target once (pre splat + cameras + masks), None when impossible."""
        if self._target_done:
            return self.target
        self._target_done = True
        pre = self.layers.get("pre")
        if not isinstance(pre, SplatLayer) or not self.cameras:
            return None
        pairs = [(v, c) for v, c in zip(self.views, self.view_cameras) if c is not None and v in self.bundle.masks]
        pairs = [pairs[i] for i in voting_views(len(pairs))]
        cams = [c for _, c in pairs]
        masks = [self.mask_of(v, c.width, c.height) for v, c in pairs]
        self.target = estimate_target(pre.gaussians.means, cams, masks)
        if self.target is not None:
            gauss = pre.gaussians.subset(self.target.indices)
            self._target_layer = SplatLayer.from_gaussians("target", gauss, ctx=self.ctx,
                                                           background=self.bundle.options.background)
        return self.target

    def focus_target(self) -> None:
        target = self.ensure_target()
        if target is not None:
            self.camera.focus(target.centre, target.radius)
        else:
            self.camera.focus(self.camera.pivot, self.scale_length * 0.5)
            self.notify("no target estimate (needs a splat pre scene, cameras and masks): focused on the pivot")

    def mask_of(self, view: str, width: int, height: int) -> np.ndarray:
        """The view's target mask (bool) at ``width x height`` (nearest-neighbour)."""
        m = self._masks.get(view)
        if m is None:
            while len(self._masks) >= MASK_CACHE:
                self._masks.pop(next(iter(self._masks)))
            m = self._masks[view] = load_mask(self.bundle.masks[view])
        return resize_nearest(m, width, height)

    # -- rendering ------------------------------------------------------------
    def picture_aspect(self, view: str | None) -> float | None:
        """Width / height the pictures must keep: the evaluation camera's or renders' on a view."""
        a = self.camera.aspect()
        if a is not None:
            return a
        if view is not None:
            for name in self.state.shown():
                layer = self.layers[name]
                if layer.kind == "renders" and layer.available(view):
                    w, h = layer.native_size(view)
                    return w / h
        return None

    def involved(self) -> list[str]:
        """Layers this frame reads: the shown scenes, plus pre for the |dD| overlays."""
        names = list(dict.fromkeys(self.state.shown()))
        if self.state.overlays.any_delta() and "pre" not in names:
            names.append("pre")
        return names

    def render_size(self, lay: Layout, scale: float, view: str | None) -> tuple[int, int]:
        """Per-picture render size: the layout's at ``scale``; on a view with a renders source
        involved, that source's own size (so every picture and |dD| share one size)."""
        if view is not None:
            for name in self.involved():
                layer = self.layers[name]
                if layer.kind == "renders" and layer.available(view):
                    return layer.native_size(view)
        return lay.render_size(scale)

    def frame(self) -> None:
        """Draw one frame into the canvas (the canvas' draw function)."""
        t_start = self.clock()
        now = t_start
        dt = min(0.1, max(0.0, now - self._last_frame))
        self._last_frame = now
        s = self.state
        if self.camera.mode != s.camera_mode:
            self.camera.set_mode(s.camera_mode)
        f, r, u = s.movement()
        if (f or r or u) and self.can_move:
            self.camera.move(f, r, u, dt, self.modifiers)
        if self._flight:
            self.camera.set_camera(self._flight.pop(0))
            self.state = self.state.moved()  # between evaluation views: no view's mask applies
            if not self._flight:
                self._flight_done = True
        key = self.camera.pose_key()
        if key != self._pose_key:
            self._pose_key = key
            self._last_motion = now
            self.live_stale = bool(self.live)
        if self.can_move and self.camera.snapped is None:
            self.state = self.state.moved()
        view = self.current_view()
        x0, y0, area_w, area_h = self.view_area()
        lay = layout(self.state.compare, area_w, area_h, aspect=self.picture_aspect(view), wipe=self.state.wipe,
                     x0=x0, y0=y0)
        self.last_layout = lay
        since = now - self._last_motion
        full_w, full_h = lay.render_size(1.0)
        scale = self.policy.quantised(self.policy.scale(since, full_w * full_h * len(self.involved())))
        if self.recorder is not None:
            scale = 1.0  # recordings are written at full resolution
        rw, rh = self.render_size(lay, scale, view)
        cam = self.camera.render_camera(rw, rh)
        self.last_camera, self.last_scale = cam, scale
        pictures = self.render_pictures(cam, view)
        if scale >= 1.0 and since >= self.policy.still_delay:
            self.update_live(cam, view)
        texture = self.canvas_context.get_current_texture()
        enc = self.ctx.encoder()
        self.compositor.record(enc, texture.create_view(), self.format, lay, pictures)
        self.ctx.submit(enc)
        self._view_captures(lay, pictures, cam)
        if self.gui is not None:
            self.gui.render()
        for shot in [p for p in self._pending_shots if p[0] == "window"]:
            self._pending_shots.remove(shot)
            self._save_window(texture, shot[1])
        self.frames += 1
        self.frame_seconds = self.clock() - t_start
        if self._flight_done:
            self._flight_done = False
            self.set_recording(False)
        self._busy = (any(self.state.movement()) or self._drag is not None or scale < 1.0 or bool(self._flight)
                      or self.state.recording or bool(self._pending_shots) or since < self.policy.still_delay)
        if self._busy:
            self.request_draw()

    def busy(self) -> bool:
        """Whether the last frame asked for more: the camera moved within the still delay or is
        still at reduced resolution, keys are held, a drag, recording or screenshot is under way."""
        return self._busy

    def pending_screenshots(self) -> list:
        """(kind, path) of the screenshots not written yet."""
        return list(self._pending_shots)

    def render_pictures(self, cam, view: str | None) -> list:
        """Render and overlay every shown scene; returns [(buffer, width, height) or None] per picture."""
        s, ov = self.state, self.state.overlays
        ckey = camera_key(cam)
        if self._frame_cache.get("key") != (ckey, view):
            self._frame_cache = {"key": (ckey, view)}
        fc = self._frame_cache
        for name in self.involved():
            self.layers[name].load()  # loading a scene file is not rendering time
        t0 = self.clock()
        rendered = 0
        images: dict[str, PlaneImage | None] = {}
        for name in self.involved():
            layer = self.layers[name]
            before = layer.renders_done
            images[name] = layer.image(cam, view)
            rendered += layer.renders_done - before
        if rendered:
            self.policy.observe(rendered * cam.width * cam.height, self.clock() - t0)
        pictures = []
        enc = self.ctx.encoder()
        self.last_delta = {}
        for i, name in enumerate(s.shown()):
            img = images.get(name)
            if img is None:
                pictures.append(None)
                continue
            settings = OverlaySettings(
                depth=ov.depth, delta_heat=ov.delta, changed=ov.changed, outline=ov.outline and view is not None,
                probes=ov.probes and view is not None, colormap=ov.colormap, opacity=ov.opacity,
                depth_range=ov.depth_range, heat_range=ov.delta_range,
                outline_px=max(1, int(round(1.5 * img.width / max(1, self.last_layout.rects[0][2])))),
            )
            if ov.depth and ov.depth_auto:
                rng = fc.get(("depth", name))
                if rng is None:
                    rng = fc[("depth", name)] = self.overlay.depth_range(img) or (0.0, 1.0)
                settings.depth_range = rng
            pre = images.get("pre") if ov.any_delta() and name != "pre" else None
            if not (self.layers["pre"].has_depth and self.layers[name].has_depth):
                pre = None  # renders without depth: no |dD|
            if pre is not None and pre.size == img.size:
                st = fc.get(("delta", name))
                if st is None:
                    st = fc[("delta", name)] = delta_stats(self.ctx, pre, img)
                settings.delta = st
                self.last_delta[name] = st
                if ov.delta_auto:
                    settings.heat_range = (0.0, st.hi if st.hi > 0 else 1.0)
            else:
                pre = None
            mask = self.mask_buffer(view, img.width, img.height) if settings.outline else None
            ids = self.probe_buffer(name, view, img.width, img.height) if settings.probes else None
            out = self._pic_buffers[i] = self.overlay.output_buffer(img.width, img.height, self._pic_buffers[i])
            self.overlay.record(enc, img, settings, out, pre=pre, mask=mask, probe_ids=ids)
            pictures.append((out, img.width, img.height))
        self.ctx.submit(enc)
        return pictures

    def mask_buffer(self, view: str | None, width: int, height: int):
        if view is None or view not in self.bundle.masks:
            return None
        key = (view, width, height)
        buf = self._mask_buffers.get(key)
        if buf is None:
            if len(self._mask_buffers) > 8:
                self._mask_buffers.clear()
            buf = self._mask_buffers[key] = self.overlay.upload_mask(self.mask_of(view, width, height))
        return buf

    def probe_buffer(self, name: str, view: str | None, width: int, height: int):
        """Probe instance ids of the chosen cached probe for (scene, view) at the render size, or None."""
        from .probe_masks import cached_masks, instance_ids

        if view is None or self.results is None:
            return None
        key = (name, view)
        entry = self._probe_buffers.get(key)
        if entry is None:
            if len(self._probe_buffers) >= 16:
                self._probe_buffers.clear()
            layer = self.layers[name]
            idx = self.views.index(view)
            try:
                rgb = layer.host_rgb(view, self.view_cameras[idx])
                found = cached_masks(self.results.probe_cache, self.results.probes, rgb,
                                     self.results.prompt or self.bundle.prompt)
            except Exception as e:  # noqa: BLE001 - a broken cache must not take the viewer down
                self.notify(f"probe cache: {e}")
                found = []
            entry = self._probe_buffers[key] = {"found": found, "buffers": {}}
        self.probe_found = entry["found"]
        if not entry["found"]:
            return None
        pm = entry["found"][min(self.probe_choice, len(entry["found"]) - 1)]
        bkey = (pm.probe, width, height)
        buf = entry["buffers"].get(bkey)
        if buf is None:
            ids = instance_ids(pm.masks)
            buf = entry["buffers"][bkey] = self.overlay.upload_ids(resize_nearest(ids, width, height))
        return buf

    # -- live geometric axis -----------------------------------------------------
    def update_live(self, cam, view: str | None) -> None:
        """Measure acc_depth of each shown non-pre scene at this viewpoint (once per still pose)."""
        key = (camera_key(cam), view, self.state.shown())
        if key == self._live_key:
            self.live_stale = False
            return
        self._live_key = key
        self.live = {}
        self.live_stale = False
        targets = [n for n in dict.fromkeys(self.state.shown()) if n != "pre"]
        if not targets:
            self.live_note = "pre vs pre: show a method to measure it"
            return
        pre_layer = self.layers["pre"]
        if view is not None and self.view_cameras[self.views.index(view)] is not None:
            mcam = self.view_cameras[self.views.index(view)]
            kind = "evaluation"
        elif view is not None:
            mcam, kind = cam, "evaluation"
        else:
            mcam, kind = cam, "projected"
        if not pre_layer.has_depth:
            self.live_note = "pre has no depth (renders without a depth folder): no geometric axis"
            return
        pre = pre_layer.image(mcam, view)
        if pre is None:
            self.live_note = "pre has no image here (renders source off the evaluation views)"
            return
        if kind == "evaluation":
            mask = self.mask_of(view, pre.width, pre.height)
        else:
            mask = self.projected_target_mask(mcam, pre)
            if mask is None:
                self.live_note = "no target estimate: the live axis needs a mask off the evaluation views"
                return
        self.live_note = ""
        for name in targets:
            if not self.layers[name].has_depth:
                continue
            img = self.layers[name].image(mcam, view)
            if img is None or img.size != pre.size:
                continue
            self.live[name] = live_axis(self.ctx, pre, img, mask, kind)

    def projected_target_mask(self, cam, pre: PlaneImage) -> np.ndarray | None:
        """The estimated target's visible silhouette at ``cam`` (bool (H, W)), or None."""
        if self.ensure_target() is None or self._target_layer is None:
            return None
        t = self._target_layer.image(cam)
        from r360gpu.render.rasterize import planes_to_numpy

        tp = planes_to_numpy(self.ctx, t.buffer, t.width, t.height)
        pp = planes_to_numpy(self.ctx, pre.buffer, pre.width, pre.height)
        plane = "depth" if pre.depth_plane == 4 else "median_depth"
        return projected_mask(tp["alpha"], tp[plane], pp[plane])

    # -- captures -----------------------------------------------------------------
    def render_view_image(self, lay: Layout, pictures: list) -> np.ndarray:
        """The composed pictures (no panels) as (H, W, 4) uint8 RGBA, cropped to the pictures."""
        import wgpu

        fb_w, fb_h = self.framebuffer_size()
        tex = self.ctx.device.create_texture(size=(fb_w, fb_h, 1), format=CAPTURE_FORMAT,
                                             usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)
        enc = self.ctx.encoder()
        self.compositor.record(enc, tex.create_view(), CAPTURE_FORMAT, lay, pictures)
        self.ctx.submit(enc)
        img = capture.read_texture(self.ctx.device, tex)
        x0 = min(r[0] for r in lay.rects)
        y0 = min(r[1] for r in lay.rects)
        x1 = max(r[0] + r[2] for r in lay.rects)
        y1 = max(r[1] + r[3] for r in lay.rects)
        return img[max(0, y0):y1, max(0, x0):x1].copy()

    def _shot_name(self) -> str:
        s = self.state
        shown = "_vs_".join(s.shown())
        where = self.current_view() or "free"
        return f"{self.bundle.name}_{shown}_{where}_{capture.timestamp()}"

    def request_screenshot(self, kind: str = "view", path: str | Path | None = None) -> None:
        """Save a screenshot at the end of the next frame: ``kind`` "view" (the pictures only) or
        "window" (with the panels); ``path`` None: a new file in :attr:`capture_dir`."""
        if kind not in ("view", "window"):
            raise ValueError(f"screenshot kind must be 'view' or 'window', got {kind!r}")
        self._pending_shots.append((kind, Path(path) if path is not None else None))
        self.request_draw()

    def _view_captures(self, lay: Layout, pictures: list, cam) -> None:
        shots = [p for p in self._pending_shots if p[0] == "view"]
        recording = self.recorder is not None
        if not (shots or recording):
            return
        img = self.render_view_image(lay, pictures)
        for shot in shots:
            self._pending_shots.remove(shot)
            path = shot[1] or self._unique(self.capture_dir / f"{self._shot_name()}.png")
            self.last_shot = capture.save_png(path, img)
            self.notify(f"screenshot: {path}")
        if recording:
            # One frame per new camera: a resting camera adds nothing.
            key = camera_key(cam)
            if key != self._last_recorded:
                self._last_recorded = key
                self.recorder.add(img, cam)
            if self.recorder.full:
                self.set_recording(False)

    def _save_window(self, texture, path: Path | None) -> None:
        if not self.window_copyable:
            self.notify("this window cannot be read back; saving the view only")
            self._pending_shots.append(("view", path))
            return
        img = capture.read_texture(self.ctx.device, texture)
        path = path or self._unique(self.capture_dir / f"{self._shot_name()}_window.png")
        self.last_shot = capture.save_png(path, img)
        self.notify(f"screenshot: {path}")

    @staticmethod
    def _unique(path: Path) -> Path:
        k, p = 1, path
        while p.exists():
            p = path.with_name(f"{path.stem}_{k}{path.suffix}")
            k += 1
        return p

    def fly_evaluation_path(self, steps: int = 8) -> None:
        """Record a fly-through of the evaluation cameras: ``steps`` frames from each to the next."""
        if len(self.cameras) < 2 or not self.can_move:
            self.notify("a fly-through needs at least two evaluation cameras and a splat scene")
            return
        first = self.cameras[0]
        self._flight = capture.path_through(self.cameras, steps, first.width, first.height)
        self._flight_done = False
        self.set_recording(True)
        self.request_draw()

    def set_recording(self, on: bool) -> None:
        """Start or stop recording the camera path to numbered PNGs (+ cameras.json)."""
        if on and self.recorder is None:
            self._last_recorded = None
            folder = self._unique(self.capture_dir / f"record_{self.bundle.name}_{capture.timestamp()}")
            self.recorder = capture.PathRecorder(folder)
            self.notify(f"recording to {self.recorder.folder}")
        elif not on and self.recorder is not None:
            self._flight = []
            folder = self.recorder.close()
            self.notify(f"recorded {len(self.recorder.cameras)} frames to {folder}")
            self.recorder = None
        if self.state.recording != on:
            self.state = replace(self.state, recording=on)

    # -- lifetime ---------------------------------------------------------------------
    def close(self) -> None:
        """Stop a recording and free the device memory of every scene."""
        if self.recorder is not None:
            self.set_recording(False)
        for layer in self.layers.values():
            layer.release()
        if self._target_layer is not None:
            self._target_layer.release()
