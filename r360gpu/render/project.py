"""Host side of ``shaders/render_project.wgsl``: projection of every Gaussian.

The scene's parameter and SH buffers can exceed one storage binding (3M
Gaussians of degree 3 hold 576 MB of SH), so the kernel runs over chunks of
Gaussians with a window of each input bound per chunk.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..gpu.context import BufferRange, GpuContext
from ..gpu.shaders import workgroup_threads
from ..gpu.uniforms import uniform
from .conventions import FRUSTUM_GUARD, TILE
from .shader_pipelines import pipeline
from .scene import PARAM_FLOATS, DeviceScene
from .scratch import Scratch

#: Invocations per workgroup of render_project.wgsl, one per Gaussian (the shader states it).
WG = workgroup_threads("render_project")
#: The WGSL names of render_project.wgsl's bindings, in the order the projection binds them.
PROJECT_BINDINGS = ("p", "params", "sh", "pos_op", "conic", "rgb", "rect", "depth_key", "idx", "row_counts")

# Chunks start at multiples of this many Gaussians so every window offset is a
# multiple of 32 bytes (8 x 12 bytes for degree-0 SH).
_CHUNK_ALIGN = 8


@dataclass
class Projected:
    """Per-Gaussian results of the projection (device buffers, N entries each).

    pos_op (u, v, z, opacity) f32x4; conic (a, b, c, 0) f32x4; rgb (r, g, b, 0)
    f32x4; rect (x0, y0, x1, y1) u32x4 tile rectangle; depth_key u32 (float bits
    of z, 0xffffffff if culled); idx u32 (0..N-1); row_counts u32 per tile row
    (the buffer holds one more u32, free for the caller).
    """

    pos_op: object
    conic: object
    rgb: object
    rect: object
    depth_key: object
    idx: object
    row_counts: object


def camera_arrays(camera) -> dict:
    """Validated camera parameters as numpy values (InputError on bad cameras)."""
    name = getattr(camera, "name", "") or "camera"
    try:
        R = np.asarray(camera.R, dtype=np.float64)
        t = np.asarray(camera.t, dtype=np.float64).reshape(-1)
        fx, fy, cx, cy = (float(getattr(camera, k)) for k in ("fx", "fy", "cx", "cy"))
        width, height = int(camera.width), int(camera.height)
    except (AttributeError, TypeError, ValueError) as e:
        raise InputError(f"{name}: not a usable camera ({e})") from None
    if R.shape != (3, 3) or t.shape != (3,):
        raise InputError(f"{name}: R must be (3, 3) and t (3,), got {R.shape} and {t.shape}")
    if not (np.isfinite(R).all() and np.isfinite(t).all() and np.isfinite([fx, fy, cx, cy]).all()):
        raise InputError(f"{name}: camera parameters are not finite")
    if fx <= 0 or fy <= 0 or width <= 0 or height <= 0:
        raise InputError(f"{name}: need fx, fy > 0 and a positive image size, got fx={fx}, fy={fy}, {width}x{height}")
    return dict(R=R, t=t, fx=fx, fy=fy, cx=cx, cy=cy, width=width, height=height, name=name)


def chunk_size(ctx: GpuContext, sh_stride: int) -> int:
    """Gaussians per projection chunk: the inputs' windows must fit one binding."""
    per = ctx.max_binding_bytes // max(PARAM_FLOATS * 4, sh_stride * 4)
    per = per // _CHUNK_ALIGN * _CHUNK_ALIGN
    if per == 0:
        raise InputError(f"storage bindings of {ctx.max_binding_bytes} bytes cannot hold one chunk of Gaussians")
    return min(per, WG * ctx.max_workgroups**2)


def project(ctx: GpuContext, enc, scene: DeviceScene, cam: dict, tiles: tuple[int, int],
            near: float, scratch: Scratch, antialiased: bool = False) -> Projected:
    """Record the projection of all Gaussians of ``scene`` for camera ``cam`` on ``enc``.

    ``cam`` comes from :func:`camera_arrays`; ``tiles`` is (tiles_x, tiles_y);
    ``antialiased`` multiplies opacities by the antialiasing compensation.
    """
    n = scene.n
    gx, gy = tiles
    out = Projected(
        pos_op=scratch.get("proj.pos_op", n * 16),
        conic=scratch.get("proj.conic", n * 16),
        rgb=scratch.get("proj.rgb", n * 16),
        rect=scratch.get("proj.rect", n * 16),
        depth_key=scratch.get("proj.depth_key", n * 4),
        idx=scratch.get("proj.idx", n * 4),
        row_counts=scratch.get("proj.row_counts", (gy + 1) * 4),
    )
    enc.clear_buffer(out.row_counts, 0, out.row_counts.size)
    R = cam["R"]
    t = cam["t"] + R @ scene.origin  # the centres are stored relative to scene.origin (DeviceScene)
    centre = -R.T @ t
    fx, fy, cx, cy, w, h = (cam[k] for k in ("fx", "fy", "cx", "cy", "width", "height"))
    guard_x = FRUSTUM_GUARD * 0.5 * w / fx
    guard_y = FRUSTUM_GUARD * 0.5 * h / fy
    lims = (cx / fx + guard_x, (w - cx) / fx + guard_x, cy / fy + guard_y, (h - cy) / fy + guard_y)
    pipe = pipeline(ctx, "render_project", "main", PROJECT_BINDINGS)
    per = chunk_size(ctx, scene.sh_stride)
    whole = [BufferRange(b, 0, max(16, n * s)) for b, s in
             ((out.pos_op, 16), (out.conic, 16), (out.rgb, 16), (out.rect, 16), (out.depth_key, 4), (out.idx, 4))]
    rows = BufferRange(out.row_counts, 0, gy * 4)
    for base in range(0, n, per):
        count = min(per, n - base)
        rot = {f"r{i}{j}": R[i, j] for i in range(3) for j in range(3)}
        params = uniform(
            ctx, "render_project", **rot, tx=t[0], ty=t[1], tz=t[2], cam_x=centre[0], cam_y=centre[1],
            cam_z=centre[2], fx=fx, fy=fy, cx=cx, cy=cy, lim_x_neg=lims[0], lim_x_pos=lims[1], lim_y_neg=lims[2],
            lim_y_pos=lims[3], near=near, tiles_x=gx, tiles_y=gy, n=count, base=base, sh_degree=scene.sh_degree,
            sh_stride=scene.sh_stride, antialiased=bool(antialiased),
        )
        ctx.dispatch(
            enc, pipe,
            [
                params,
                BufferRange(scene.params, base * PARAM_FLOATS * 4, count * PARAM_FLOATS * 4),
                BufferRange(scene.sh, base * scene.sh_stride * 4, count * scene.sh_stride * 4),
                *whole,
                rows,
            ],
            ctx.grid(-(-count // WG)),
        )
    return out


def tile_grid(width: int, height: int) -> tuple[int, int]:
    """(tiles_x, tiles_y) covering a width x height image with TILE x TILE tiles."""
    return -(-width // TILE), -(-height // TILE)
