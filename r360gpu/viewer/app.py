"""The viewer application: a rendercanvas canvas, r360gpu's renderer, overlays, composition and imgui.

:class:`ViewerApp` is the hub: it holds the bundle, the layers (one per
scene), the camera and the :class:`~r360gpu.viewer.state.ViewerState`, configures
the canvas with r360gpu's device (one wgpu device is shared by the canvas,
imgui and r360gpu) and hands each job to one part:

* :class:`r360gpu.viewer.input.Input` -- keys, mouse and the state machine's actions;
* :class:`r360gpu.viewer.frame.FrameLoop` -- one frame, start to end, with the
  panels docked beside the pictures (:mod:`r360gpu.viewer.docking`);
* :class:`r360gpu.viewer.frame_pictures.Pictures` -- rendering and overlays of the shown scenes;
* :class:`r360gpu.viewer.live.LiveMeter` -- the live geometric axis at the viewpoint;
* :class:`r360gpu.viewer.target.SceneTarget` -- the 3D target estimate (focus, masks
  away from the evaluation views);
* :class:`r360gpu.viewer.capture.Captures` -- screenshots, recordings, fly-throughs;
* :class:`r360gpu.viewer.panels.Panels` -- the imgui panels and the pane labels.

Any rendercanvas canvas works (glfw for the desktop app, the offscreen
canvas for headless tests).
"""
from __future__ import annotations

import time
from pathlib import Path

from r360gpu.gpu import get_context

from .camera import CameraController, nearest_camera, scene_scale
from .capture import Captures
from .compose import Compositor
from .frame import FrameLoop
from .input import Input
from .layers import SplatLayer, build_layers
from .residuals import ResidualHighlight
from .live import LiveMeter
from .overlays import OverlayPass
from .frame_pictures import Pictures
from .quality import ResolutionPolicy
from .state import Action, ViewerState
from .target import SceneTarget

#: Seconds a status message stays on screen.
MESSAGE_SECONDS = 4.0


def _texture_usage():
    import wgpu

    return wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC


class ViewerApp:
    """The viewer on ``canvas`` for ``bundle`` (:class:`r360gpu.bundle.Bundle`).

    results: optional :class:`r360gpu.viewer.results.SceneResults`; ctx: the
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
        self.messages: list[tuple[float, str]] = []
        self.closed = False
        self.input = Input(self)
        self.pictures = Pictures(self)
        self.meter = LiveMeter(self)
        self.target = SceneTarget(self)
        self.residuals = ResidualHighlight(self)
        self.captures = Captures(self, self.capture_dir)
        self.loop = FrameLoop(self)
        self._configure_canvas()
        self.gui = None
        if gui:
            from .panels import Panels

            self.gui = Panels(self)
        canvas.add_event_handler(self.input.on_event, "key_down", "key_up", "pointer_down", "pointer_move",
                                 "pointer_up", "wheel")
        if self.view_cameras and self.view_cameras[0] is not None:
            self.camera.set_camera(self.view_cameras[0])
        self.teleported()

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

    def request_draw(self) -> None:
        self.canvas.request_draw()

    def notify(self, text: str) -> None:
        """Show ``text`` in the status line for a few seconds."""
        self.messages.append((self.clock(), text))
        self.messages = self.messages[-5:]

    def quit(self) -> None:
        """Close the window (Esc, Q); the run loop then ends and :meth:`close` frees the scenes."""
        self.closed = True
        close = getattr(self.canvas, "close", None)
        if close is not None:
            close()

    # -- views ----------------------------------------------------------------
    def current_view(self) -> str | None:
        """The evaluation view the camera is on, or None."""
        s = self.state
        if s.on_view and s.view_index is not None:
            return self.views[s.view_index]
        return None

    def teleported(self) -> None:
        self.loop.teleported()

    def jump_to_view(self, index: int) -> None:
        """Put the camera on evaluation view ``index``."""
        self.state = self.state.at_view(index)
        cam = self.view_cameras[index]
        if cam is not None:
            self.camera.set_camera(cam)
        self.teleported()

    def jump_to_worst_view(self) -> None:
        """Put the camera on scene A's worst evaluation view by the results file (J)."""
        name = self.state.name_a
        method = None if self.results is None else self.results.methods.get(name)
        worst = None if method is None else method.worst_view(self.views)
        if worst is None:
            self.notify(f"no per-view results for {name!r}: open the viewer with --results and show a method as A")
            return
        self.jump_to_view(self.views.index(worst))
        self.notify(f"worst view of {name}: {worst}")

    def snap(self) -> None:
        """Jump to the evaluation camera closest to the current pose."""
        if not self.cameras:
            return
        idx = nearest_camera(self.camera.position, self.camera.rotation, self.cameras, self.scale_length)
        self.jump_to_view(self.view_cameras.index(self.cameras[idx]))

    def set_state(self, state: ViewerState) -> None:
        self.state = state
        self.request_draw()

    # -- the parts' entry points (keys, widgets, scripts and tests use these) ---------
    def key(self, key: str, modifiers=(), down: bool = True) -> None:
        self.input.key(key, modifiers, down)

    def apply(self, action: Action) -> None:
        self.input.apply(action)

    def on_event(self, ev: dict) -> None:
        self.input.on_event(ev)

    def frame(self) -> None:
        self.loop.frame()

    def busy(self) -> bool:
        """Whether the last frame asked for more: the camera moved within the still delay or is
        still at reduced resolution, keys are held, a drag, recording or screenshot is under way."""
        return self.loop.busy

    def ensure_target(self):
        return self.target.ensure()

    def request_screenshot(self, kind: str = "view", path: str | Path | None = None) -> None:
        self.captures.request_screenshot(kind, path)

    def pending_screenshots(self) -> list:
        """(kind, path) of the screenshots not written yet."""
        return list(self.captures.pending)

    def fly_evaluation_path(self, steps: int = 8) -> None:
        self.captures.fly_evaluation_path(steps)

    def set_recording(self, on: bool) -> None:
        self.captures.set_recording(on)

    # What the last frame did, for the panels and tests.
    last_layout = property(lambda self: self.loop.last_layout)
    last_camera = property(lambda self: self.loop.last_camera)
    last_scale = property(lambda self: self.loop.last_scale)
    frames = property(lambda self: self.loop.frames)
    frame_seconds = property(lambda self: self.loop.frame_seconds)
    live = property(lambda self: self.meter.live)
    live_note = property(lambda self: self.meter.note)
    live_stale = property(lambda self: self.meter.stale)
    last_delta = property(lambda self: self.pictures.last_delta)
    probe_found = property(lambda self: self.pictures.probe_found)
    recorder = property(lambda self: self.captures.recorder)
    last_shot = property(lambda self: self.captures.last_shot)

    # -- lifetime ---------------------------------------------------------------------
    def close(self) -> None:
        """Stop a recording and free the device memory of every scene."""
        if self.captures.recorder is not None:
            self.captures.set_recording(False)
        for layer in self.layers.values():
            layer.release()
        self.residuals.release()
        self.target.release()
