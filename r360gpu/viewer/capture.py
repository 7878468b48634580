"""Screenshots and camera-path recordings.

* :func:`read_texture`: an rgba8 / bgra8 texture (the window's or an
  offscreen one) as an (H, W, 4) uint8 RGBA array.  ``*-srgb`` textures hold
  sRGB-encoded bytes, which is what a PNG stores, so no conversion is needed.
* :func:`save_png`: write an RGBA or RGB array as PNG (atomically).
* :class:`PathRecorder`: numbered PNG frames of the live view into a folder,
  plus ``cameras.json`` with every frame's camera so the path can be
  replayed or rendered again.
* :func:`path_through`: cameras interpolated between consecutive evaluation
  cameras (a fly-through of the evaluation path).
* :class:`Captures`: the app's screenshots (of the pictures, or of the whole
  window with the panels), recordings and fly-throughs, taken at the end of
  a frame.
"""
from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

import cv2
import numpy as np

from r360gpu.errors import InputError
from r360gpu.io.camera import Camera
from r360gpu.util.atomic import write_bytes, write_text

from .camera import interpolate

#: Recordings stop by themselves after this many frames.
MAX_RECORD_FRAMES = 600
#: Offscreen format of view-only captures.
CAPTURE_FORMAT = "rgba8unorm"


def read_texture(device, texture) -> np.ndarray:
    """(H, W, 4) uint8 RGBA copy of ``texture`` (format rgba8* or bgra8*; needs COPY_SRC usage)."""
    w, h = int(texture.size[0]), int(texture.size[1])
    bpr = -(-w * 4 // 256) * 256  # copies need rows aligned to 256 bytes
    raw = device.queue.read_texture({"texture": texture, "mip_level": 0, "origin": (0, 0, 0)},
                                    {"offset": 0, "bytes_per_row": bpr, "rows_per_image": h}, (w, h, 1))
    a = np.frombuffer(raw, np.uint8).reshape(h, bpr)[:, : w * 4].reshape(h, w, 4)
    fmt = str(texture.format)
    if fmt.startswith("bgra"):
        a = a[..., [2, 1, 0, 3]]
    elif not fmt.startswith("rgba"):
        raise ValueError(f"cannot read back a texture of format {fmt}")
    return np.ascontiguousarray(a)


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Write (H, W, 3|4) uint8 RGB(A) as a PNG at ``path`` (folders created, atomic)."""
    a = np.asarray(image)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"expected an (H, W, 3|4) uint8 image, got {a.dtype} {a.shape}")
    bgr = a[..., [2, 1, 0]] if a.shape[2] == 3 else a[..., [2, 1, 0, 3]]
    ok, data = cv2.imencode(".png", np.ascontiguousarray(bgr))
    if not ok:
        raise InputError("could not encode the PNG", path)
    path = Path(path)
    write_bytes(path, data.tobytes())
    return path


def timestamp() -> str:
    """Local time as YYYYmmdd-HHMMSS (names of screenshots and recordings)."""
    return _dt.datetime.now().strftime("%Y%m%d-%H%M%S")


class PathRecorder:
    """Writes ``frame_00000.png``, ... into ``folder`` and the cameras into ``cameras.json``."""

    def __init__(self, folder: str | Path, max_frames: int = MAX_RECORD_FRAMES):
        self.folder = Path(folder)
        self.max_frames = int(max_frames)
        self.cameras: list[dict] = []

    @property
    def full(self) -> bool:
        return len(self.cameras) >= self.max_frames

    def add(self, image: np.ndarray, camera: Camera) -> Path | None:
        """Save one frame (None once ``max_frames`` frames were written)."""
        if self.full:
            return None
        i = len(self.cameras)
        path = save_png(self.folder / f"frame_{i:05d}.png", image)
        self.cameras.append({
            "frame": i, "file": path.name, "width": camera.width, "height": camera.height,
            "fx": camera.fx, "fy": camera.fy, "cx": camera.cx, "cy": camera.cy,
            "world_to_camera": camera.world_to_camera.tolist(),
        })
        return path

    def close(self) -> Path:
        """Write ``cameras.json`` (world-to-camera matrices, OpenCV axes) and return the folder."""
        write_text(self.folder / "cameras.json", json.dumps({"frames": self.cameras}, indent=1))
        return self.folder


def path_through(cameras: list[Camera], steps: int, width: int, height: int) -> list[Camera]:
    """``steps`` cameras from each evaluation camera towards the next (the last one included)."""
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    out: list[Camera] = []
    for a, b in zip(cameras, cameras[1:]):
        out += [interpolate(a, b, k / steps, width, height) for k in range(steps)]
    if cameras:
        out.append(interpolate(cameras[-1], cameras[-1], 0.0, width, height))
    return out


def unique_path(path: Path) -> Path:
    """``path``, or ``stem_1``, ``stem_2``, ... when it exists."""
    k, p = 1, path
    while p.exists():
        p = path.with_name(f"{path.stem}_{k}{path.suffix}")
        k += 1
    return p


class Captures:
    """Screenshots, recordings and fly-throughs of one :class:`r360gpu.viewer.app.ViewerApp`.

    pending: (kind, path or None) of the screenshots asked for and not yet
    written; recorder: the :class:`PathRecorder` of the recording under way
    (None when not recording); flight: cameras still to visit on a recorded
    fly-through; last_shot: the last file written.
    """

    def __init__(self, app, folder: Path):
        self.app = app
        self.folder = Path(folder)
        self.pending: list[tuple[str, Path | None]] = []
        self.recorder: PathRecorder | None = None
        self.flight: list = []
        self.flight_done = False
        self.last_shot: Path | None = None
        self._last_recorded = None

    def request_screenshot(self, kind: str = "view", path: str | Path | None = None) -> None:
        """Save a screenshot at the end of the next frame: ``kind`` "view" (the pictures only) or
        "window" (with the panels); ``path`` None: a new file in :attr:`folder`."""
        if kind not in ("view", "window"):
            raise ValueError(f"screenshot kind must be 'view' or 'window', got {kind!r}")
        self.pending.append((kind, Path(path) if path is not None else None))
        self.app.request_draw()

    def _name(self) -> str:
        app = self.app
        shown = "_vs_".join(app.state.shown())
        where = app.current_view() or "free"
        return f"{app.bundle.name}_{shown}_{where}_{timestamp()}"

    def view_image(self, lay, pictures: list) -> np.ndarray:
        """The composed pictures (no panels) as (H, W, 4) uint8 RGBA, cropped to the pictures."""
        import wgpu

        app = self.app
        fb_w, fb_h = app.framebuffer_size()
        tex = app.ctx.device.create_texture(size=(fb_w, fb_h, 1), format=CAPTURE_FORMAT,
                                            usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC)
        enc = app.ctx.encoder()
        app.compositor.record(enc, tex.create_view(), CAPTURE_FORMAT, lay, pictures)
        app.ctx.submit(enc)
        img = read_texture(app.ctx.device, tex)
        x0 = min(r[0] for r in lay.rects)
        y0 = min(r[1] for r in lay.rects)
        x1 = max(r[0] + r[2] for r in lay.rects)
        y1 = max(r[1] + r[3] for r in lay.rects)
        return img[max(0, y0):y1, max(0, x0):x1].copy()

    def after_pictures(self, lay, pictures: list, cam) -> None:
        """View screenshots and recording frames of this frame (before the panels are drawn)."""
        from .layers import camera_key

        shots = [p for p in self.pending if p[0] == "view"]
        if not (shots or self.recorder is not None):
            return
        img = self.view_image(lay, pictures)
        for shot in shots:
            self.pending.remove(shot)
            path = shot[1] or unique_path(self.folder / f"{self._name()}.png")
            self.last_shot = save_png(path, img)
            self._tell(path)
        if self.recorder is not None:
            # One frame per new camera: a resting camera adds nothing.
            key = camera_key(cam)
            if key != self._last_recorded:
                self._last_recorded = key
                self.recorder.add(img, cam)
            if self.recorder.full:
                self.set_recording(False)

    def after_panels(self, texture) -> None:
        """Window screenshots (with the panels) of this frame."""
        for shot in [p for p in self.pending if p[0] == "window"]:
            self.pending.remove(shot)
            self._save_window(texture, shot[1])

    def _save_window(self, texture, path: Path | None) -> None:
        app = self.app
        if not app.window_copyable:
            app.notify("this window cannot be read back; saving the view only")
            self.pending.append(("view", path))
            return
        img = read_texture(app.ctx.device, texture)
        path = path or unique_path(self.folder / f"{self._name()}_window.png")
        self.last_shot = save_png(path, img)
        self._tell(path)

    def _tell(self, path: Path) -> None:
        """Say where a capture went: in the status line, and on the terminal (the status line
        can be out of sight in a small window)."""
        self.app.notify(f"screenshot: {path}")
        print(f"screenshot: {Path(path).resolve()}", flush=True)

    def fly_evaluation_path(self, steps: int = 8) -> None:
        """Record a fly-through of the evaluation cameras: ``steps`` frames from each to the next."""
        app = self.app
        if len(app.cameras) < 2 or not app.can_move:
            app.notify("a fly-through needs at least two evaluation cameras and a splat scene")
            return
        first = app.cameras[0]
        self.flight = path_through(app.cameras, steps, first.width, first.height)
        self.flight_done = False
        self.set_recording(True)
        app.request_draw()

    def next_flight_camera(self):
        """The next camera of the fly-through under way, or None."""
        if not self.flight:
            return None
        cam = self.flight.pop(0)
        if not self.flight:
            self.flight_done = True
        return cam

    def set_recording(self, on: bool) -> None:
        """Start or stop recording the camera path to numbered PNGs (+ cameras.json)."""
        from dataclasses import replace

        app = self.app
        if on and self.recorder is None:
            self._last_recorded = None
            folder = unique_path(self.folder / f"record_{app.bundle.name}_{timestamp()}")
            self.recorder = PathRecorder(folder)
            app.notify(f"recording to {self.recorder.folder}")
        elif not on and self.recorder is not None:
            self.flight = []
            folder = self.recorder.close()
            app.notify(f"recorded {len(self.recorder.cameras)} frames to {folder}")
            self.recorder = None
        if app.state.recording != on:
            app.state = replace(app.state, recording=on)
