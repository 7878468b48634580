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
