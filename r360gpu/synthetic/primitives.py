"""Building blocks of the synthetic scenes: surfaces made of flat 3D Gaussians.

World frame of every synthetic scene: metres, **z up**, the floor / ground at
z = 0 near the target.

A surface is covered by a jittered grid of Gaussians ``spacing`` metres
apart.  Each Gaussian is flat (its standard deviation along the surface
normal is ``thickness`` x spacing) and about 0.55-0.75 x spacing wide in the
surface, at a random in-plane angle, so that neighbours overlap into an opaque
skin, as a trained 3DGS surface does.  Colours are the texture's albedo with
the light baked in (:func:`r360gpu.synthetic.texture.shade`).

Pieces are collected as :class:`Part` (float64 arrays and a name) and turned
into one :class:`~r360gpu.io.Gaussians` by :func:`assemble`.
:class:`Solid` is the box volume of a piece, used to decide which background
the target hides from the cameras.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..io import Gaussians
from ..io.sh import C0
from .texture import Texture, shade


@dataclass
class Part:
    """A named group of Gaussians under construction (float64 arrays, n rows each).

    means (n, 3), scales (n, 3) linear standard deviations, quats (n, 4)
    unit (w, x, y, z), opacities (n,) in [0, 1], rgb (n, 3) shaded colour in
    [0, 1].  shell: the part is a structural surface (floor, walls, ground,
    sky) rather than an object standing in the scene.
    """

    name: str
    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacities: np.ndarray
    rgb: np.ndarray
    shell: bool = False

    @property
    def n(self) -> int:
        return int(self.means.shape[0])

    @staticmethod
    def join(name: str, parts: Sequence["Part"], shell: bool = False) -> "Part":
        """One part holding the Gaussians of ``parts`` in order."""
        cat = {f: np.concatenate([getattr(p, f) for p in parts]) for f in
               ("means", "scales", "quats", "opacities", "rgb")}
        return Part(name, shell=shell, **cat)


def assemble(parts: Sequence[Part]) -> tuple[Gaussians, np.ndarray]:
    """All parts as one SH-degree-0 scene, in order, and the part index (N,) int32 of each Gaussian."""
    g = Gaussians(
        means=np.concatenate([p.means for p in parts]),
        scales=np.concatenate([p.scales for p in parts]),
        quats=np.concatenate([p.quats for p in parts]),
        opacities=np.concatenate([p.opacities for p in parts]),
        sh=rgb_to_sh(np.concatenate([p.rgb for p in parts])),
    )
    index = np.concatenate([np.full(p.n, i, np.int32) for i, p in enumerate(parts)])
    return g, index


def rgb_to_sh(rgb: np.ndarray) -> np.ndarray:
    """(n, 3) colours in [0, 1] -> (n, 1, 3) DC coefficients (colour = C0 * dc + 0.5)."""
    return ((np.asarray(rgb, np.float64) - 0.5) / C0)[:, None, :]


def sh_to_rgb(sh: np.ndarray) -> np.ndarray:
    """(n, K, 3) coefficients -> (n, 3) float64 view-independent colour C0 * dc + 0.5."""
    return np.asarray(sh, np.float64)[:, 0, :] * C0 + 0.5


def frames_to_quats(u: np.ndarray, v: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) (m, 4) of the rotations whose columns are the
    orthonormal right-handed frames (u, v, n), each (m, 3)."""
    r = np.stack([u, v, n], axis=2)  # columns
    tr = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    pivot = np.argmax(np.stack([tr, r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], 1), axis=1)
    q = np.empty((len(r), 4))
    # Shepperd's method: divide by the largest of the four squared-component
    # combinations, which keeps every case well conditioned.
    for case in range(4):
        sel = pivot == case
        if not sel.any():
            continue
        m = r[sel]
        if case == 0:
            s = 2.0 * np.sqrt(np.maximum(1.0 + tr[sel], 1e-12))
            q[sel] = np.stack([0.25 * s, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s,
                               (m[:, 1, 0] - m[:, 0, 1]) / s], 1)
        elif case == 1:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], 1e-12))
            q[sel] = np.stack([(m[:, 2, 1] - m[:, 1, 2]) / s, 0.25 * s, (m[:, 0, 1] + m[:, 1, 0]) / s,
                               (m[:, 0, 2] + m[:, 2, 0]) / s], 1)
        elif case == 2:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2], 1e-12))
            q[sel] = np.stack([(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s, 0.25 * s,
                               (m[:, 1, 2] + m[:, 2, 1]) / s], 1)
        else:
            s = 2.0 * np.sqrt(np.maximum(1.0 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1], 1e-12))
            q[sel] = np.stack([(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s,
                               (m[:, 1, 2] + m[:, 2, 1]) / s, 0.25 * s], 1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _flat_gaussians(name, points, du, dv, normals, cell_u, cell_v, st, texture: Texture, rng, *,
                    thickness: float, opacity, shell: bool) -> Part:
    """Flat Gaussians at ``points`` (m, 3) on a surface with unit tangents du, dv and
    normals (m, 3); cell sizes (m,) along du / dv set the in-plane extent."""
    m = len(points)
    angle = rng.uniform(0.0, np.pi, m)[:, None]
    a = np.cos(angle) * du + np.sin(angle) * dv
    b = np.cross(normals, a)
    # The in-plane axes are at a random angle to the cells: size them by the cell's geometric mean.
    cell = np.sqrt(cell_u * cell_v)
    scales = np.stack([
        cell * rng.uniform(0.55, 0.75, m),
        cell * rng.uniform(0.55, 0.75, m),
        np.minimum(cell_u, cell_v) * thickness,
    ], 1)
    rgb = shade(texture(st, points), normals)
    return Part(name, points, scales, frames_to_quats(a, b, normals),
                rng.uniform(opacity[0], opacity[1], m), rgb, shell)


def surface(name: str, origin, u, v, spacing: float, texture: Texture, rng: np.random.Generator, *,
            thickness: float = 0.1, opacity=(0.88, 0.99), bump: float = 0.0, shell: bool = False) -> Part:
    """A flat parallelogram ``origin + s * u/|u| + t * v/|v|``, s in [0, |u|], t in [0, |v|].

    The normal is ``u x v`` (normalised); ``st`` given to the texture is
    (s, t) in metres.  bump: standard deviation in metres of an offset of
    each Gaussian along the normal (leafy or rough surfaces).
    """
    origin, u, v = (np.asarray(a, np.float64) for a in (origin, u, v))
    lu, lv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    du, dv = u / lu, v / lv
    nrm = np.cross(du, dv)
    nrm /= np.linalg.norm(nrm)
    nu, nv = max(1, int(np.ceil(lu / spacing))), max(1, int(np.ceil(lv / spacing)))
    cu, cv = lu / nu, lv / nv
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    s = (i.ravel() + 0.5 + rng.uniform(-0.3, 0.3, i.size)) * cu
    t = (j.ravel() + 0.5 + rng.uniform(-0.3, 0.3, j.size)) * cv
    offset = rng.normal(0.0, bump, s.size) if bump > 0 else np.zeros(s.size)
    pts = origin + s[:, None] * du + t[:, None] * dv + offset[:, None] * nrm
    m = len(pts)
    return _flat_gaussians(name, pts, np.tile(du, (m, 1)), np.tile(dv, (m, 1)), np.tile(nrm, (m, 1)),
                           np.full(m, cu), np.full(m, cv), np.stack([s, t], 1), texture, rng,
                           thickness=thickness, opacity=opacity, shell=shell)


def heightfield(name: str, x_range, y_range, spacing: float, height, texture: Texture,
                rng: np.random.Generator, *, exclude=None, shell: bool = True) -> Part:
    """Terrain ``z = height(x, y)`` over a rectangle, normals from its slope.

    height: callable (n,) x, (n,) y -> (n,) z in metres.  exclude: optional
    ((x0, x1), (y0, y1)) rectangle left empty (covered by a finer patch).
    ``st`` given to the texture is (x, y).
    """
    (x0, x1), (y0, y1) = x_range, y_range
    nx, ny = max(1, int(np.ceil((x1 - x0) / spacing))), max(1, int(np.ceil((y1 - y0) / spacing)))
    cx, cy = (x1 - x0) / nx, (y1 - y0) / ny
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    x = x0 + (i.ravel() + 0.5 + rng.uniform(-0.3, 0.3, i.size)) * cx
    y = y0 + (j.ravel() + 0.5 + rng.uniform(-0.3, 0.3, j.size)) * cy
    if exclude is not None:
        (ex0, ex1), (ey0, ey1) = exclude
        keep = ~((x > ex0) & (x < ex1) & (y > ey0) & (y < ey1))
        x, y = x[keep], y[keep]
    z = height(x, y)
    h = 1e-3
    gx = (height(x + h, y) - height(x - h, y)) / (2 * h)
    gy = (height(x, y + h) - height(x, y - h)) / (2 * h)
    du = np.stack([np.ones_like(x), np.zeros_like(x), gx], 1)
    du /= np.linalg.norm(du, axis=1, keepdims=True)
    nrm = np.stack([-gx, -gy, np.ones_like(x)], 1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    dv = np.cross(nrm, du)
    pts = np.stack([x, y, z], 1)
    m = len(pts)
    return _flat_gaussians(name, pts, du, dv, nrm, np.full(m, cx), np.full(m, cy), np.stack([x, y], 1),
                           texture, rng, thickness=0.1, opacity=(0.9, 0.99), shell=shell)


#: Face names of :func:`box`: the axis (in the box frame) the face's normal points along.
BOX_FACES = ("+z", "-z", "+x", "-x", "+y", "-y")


def box(name: str, center, size, spacing: float, texture, rng: np.random.Generator, *, yaw: float = 0.0,
        faces: Sequence[str] = ("+z", "+x", "-x", "+y", "-y"), bump: float = 0.0, shell: bool = False) -> Part:
    """The faces of a box of ``size`` (sx, sy, sz) centred at ``center``, turned by ``yaw``
    radians about z.  texture: one Texture, or a dict face name -> Texture (see
    :data:`BOX_FACES`; the bottom ``-z`` is left out by default: nobody sees it).
    ``st`` runs along the face's horizontal edge and then up (for +z: along x, y)."""
    c = np.asarray(center, np.float64)
    hx, hy, hz = (0.5 * float(s) for s in size)
    ex = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    ey = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    ez = np.array([0.0, 0.0, 1.0])
    geometry = {
        "+z": (c - hx * ex - hy * ey + hz * ez, 2 * hx * ex, 2 * hy * ey),
        "-z": (c - hx * ex + hy * ey - hz * ez, 2 * hx * ex, -2 * hy * ey),
        "+x": (c + hx * ex - hy * ey - hz * ez, 2 * hy * ey, 2 * hz * ez),
        "-x": (c - hx * ex + hy * ey - hz * ez, -2 * hy * ey, 2 * hz * ez),
        "+y": (c + hx * ex + hy * ey - hz * ez, -2 * hx * ex, 2 * hz * ez),
        "-y": (c - hx * ex - hy * ey - hz * ez, 2 * hx * ex, 2 * hz * ez),
    }
    parts = []
    for face in faces:
        tex = texture[face] if isinstance(texture, dict) else texture
        parts.append(surface(name, *geometry[face], spacing, tex, rng, bump=bump, shell=shell))
    return Part.join(name, parts, shell)


def cylinder(name: str, base, radius: float, height: float, spacing: float, texture: Texture,
             rng: np.random.Generator, *, taper: float = 0.0, top: bool = True, shell: bool = False) -> Part:
    """An upright cylinder (z axis) standing on ``base``; its radius shrinks linearly to
    ``(1 - taper) * radius`` at the top; a top disc when ``top``.  ``st`` on the side
    is (arc length, height)."""
    b = np.asarray(base, np.float64)
    n_around = max(6, int(np.ceil(2 * np.pi * radius / spacing)))
    n_up = max(1, int(np.ceil(height / spacing)))
    i, j = np.meshgrid(np.arange(n_around), np.arange(n_up), indexing="ij")
    theta = (i.ravel() + 0.5 + rng.uniform(-0.3, 0.3, i.size)) * 2 * np.pi / n_around
    z = (j.ravel() + 0.5 + rng.uniform(-0.3, 0.3, j.size)) * height / n_up
    r = radius * (1.0 - taper * z / height)
    nrm = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], 1)
    tangent = np.stack([-np.sin(theta), np.cos(theta), np.zeros_like(theta)], 1)
    up = np.tile([0.0, 0.0, 1.0], (len(z), 1))
    pts = b + r[:, None] * nrm + z[:, None] * up
    m = len(pts)
    side = _flat_gaussians(name, pts, tangent, up, nrm, 2 * np.pi * r / n_around, np.full(m, height / n_up),
                           np.stack([theta * radius, z], 1), texture, rng, thickness=0.1,
                           opacity=(0.9, 0.99), shell=shell)
    if not top:
        return side
    cap = disc(name, b + [0.0, 0.0, height], radius * (1.0 - taper), spacing, texture, rng, shell=shell)
    return Part.join(name, [side, cap], shell)


def disc(name: str, center, radius: float, spacing: float, texture: Texture, rng: np.random.Generator, *,
         shell: bool = False) -> Part:
    """A horizontal disc facing up (sunflower-spiral sampling); ``st`` is (x, y) from the centre."""
    c = np.asarray(center, np.float64)
    m = max(3, int(np.ceil(np.pi * radius**2 / spacing**2)))
    k = np.arange(m) + 0.5
    rr = radius * np.sqrt(k / m)
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    st = np.stack([rr * np.cos(phi), rr * np.sin(phi)], 1)
    pts = c + np.concatenate([st, np.zeros((m, 1))], 1)
    cell = np.full(m, np.sqrt(np.pi / m) * radius)
    return _flat_gaussians(name, pts, np.tile([1.0, 0, 0], (m, 1)), np.tile([0, 1.0, 0], (m, 1)),
                           np.tile([0, 0, 1.0], (m, 1)), cell, cell, st, texture, rng,
                           thickness=0.1, opacity=(0.9, 0.99), shell=shell)


def _sphere_directions(m: int) -> np.ndarray:
    """(m, 3) near-uniform unit vectors (Fibonacci sphere)."""
    k = np.arange(m) + 0.5
    z = 1.0 - 2.0 * k / m
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = k * np.pi * (3.0 - np.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def _tangent_frames(nrm: np.ndarray):
    helper = np.where(np.abs(nrm[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    du = np.cross(helper, nrm)
    du /= np.linalg.norm(du, axis=1, keepdims=True)
    return du, np.cross(nrm, du)


def blob(name: str, center, radii, spacing: float, texture: Texture, rng: np.random.Generator, *,
         depth: float = 0.25, opacity=(0.75, 0.97), shell: bool = False) -> Part:
    """Leafy foliage: an ellipsoid shell of leaf-like Gaussians (flat, randomly tilted).

    Leaves sit at 1 - U(0, depth) of the radius along random directions; the
    bottom and the inner leaves are darker (self-shadowing).  ``st`` is
    (azimuth x mean radius, z) in metres.
    """
    c = np.asarray(center, np.float64)
    radii = np.asarray(radii, np.float64)
    a, b, cc = radii
    p = 1.6075  # Knud Thomsen's ellipsoid-area approximation
    area = 4 * np.pi * (((a * b) ** p + (a * cc) ** p + (b * cc) ** p) / 3) ** (1 / p)
    m = max(8, int(np.ceil(area / spacing**2)))
    dirs = rng.normal(size=(m, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    shrink = 1.0 - rng.uniform(0.0, depth, m)
    pts = c + dirs * radii * shrink[:, None]
    outward = dirs / radii
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    tilt = rng.normal(0.0, 0.6, (m, 3))
    nrm = outward + tilt
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    du, dv = _tangent_frames(nrm)
    st = np.stack([np.arctan2(dirs[:, 1], dirs[:, 0]) * radii[:2].mean(), pts[:, 2]], 1)
    cell = np.full(m, spacing)
    part = _flat_gaussians(name, pts, du, dv, nrm, cell, cell * 0.7, st, texture, rng,
                           thickness=0.15, opacity=opacity, shell=shell)
    # Self-shadowing: inner leaves and the underside of the crown get less light.
    occl = (1.0 - 1.2 * (1.0 - shrink)) * (0.8 + 0.2 * dirs[:, 2])
    part.rgb = np.clip(part.rgb * np.clip(occl, 0.45, 1.0)[:, None], 0.0, 1.0)
    return part


def dome(name: str, center, radius: float, spacing: float, texture: Texture, rng: np.random.Generator, *,
         min_elevation: float = -0.2, shell: bool = True) -> Part:
    """A sky dome: a sphere of inward-facing flat Gaussians above ``min_elevation`` radians,
    unshaded (the sky is the light); ``st`` is (azimuth, elevation) in radians."""
    c = np.asarray(center, np.float64)
    m_full = int(np.ceil(4 * np.pi * radius**2 / spacing**2))
    dirs = _sphere_directions(m_full)
    dirs = dirs[dirs[:, 2] > np.sin(min_elevation)]
    m = len(dirs)
    pts = c + radius * dirs
    nrm = -dirs
    du, dv = _tangent_frames(nrm)
    cell = np.full(m, spacing)
    scales = np.stack([cell * 0.75, cell * 0.75, cell * 0.05], 1)
    st = np.stack([np.arctan2(dirs[:, 1], dirs[:, 0]), np.arcsin(np.clip(dirs[:, 2], -1, 1))], 1)
    rgb = np.clip(texture(st, pts), 0.0, 1.0)
    return Part(name, pts, scales, frames_to_quats(du, dv, nrm), np.full(m, 0.99), rgb, shell)


@dataclass(frozen=True)
class Solid:
    """A box volume (centre (3,), size (3,) metres, yaw radians about z): the part of
    the target that blocks lines of sight."""

    center: tuple
    size: tuple
    yaw: float = 0.0

    def _rotation(self) -> np.ndarray:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # box frame -> world

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: which of ``points`` (n, 3) lie inside the box (boundary included)."""
        local = (np.asarray(points, np.float64) - np.asarray(self.center, np.float64)) @ self._rotation()
        return np.all(np.abs(local) <= 0.5 * np.asarray(self.size, np.float64), axis=1)

    def blocks(self, eye, points: np.ndarray) -> np.ndarray:
        """(n,) bool: the segment from ``eye`` (3,) to each of ``points`` (n, 3) passes
        through the box (a point inside the box, or on its far side, counts as blocked)."""
        rot = self._rotation()
        o = (np.asarray(eye, np.float64) - np.asarray(self.center, np.float64)) @ rot
        d = (np.asarray(points, np.float64) - np.asarray(eye, np.float64)) @ rot
        half = 0.5 * np.asarray(self.size, np.float64)
        t_in = np.full(len(d), -np.inf)
        t_out = np.full(len(d), np.inf)
        for k in range(3):
            dk = d[:, k]
            parallel = np.abs(dk) < 1e-12
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (-half[k] - o[k]) / dk
                t2 = (half[k] - o[k]) / dk
            lo = np.where(parallel, np.where(abs(o[k]) <= half[k], -np.inf, np.inf), np.minimum(t1, t2))
            hi = np.where(parallel, np.where(abs(o[k]) <= half[k], np.inf, -np.inf), np.maximum(t1, t2))
            t_in = np.maximum(t_in, lo)
            t_out = np.minimum(t_out, hi)
        # Blocked when the segment (t in [0, 1]) enters the box before reaching the point.
        return (t_in < t_out) & (t_out > 0.0) & (t_in < 1.0 - 1e-9)
