"""Procedural appearance for the synthetic scenes: smooth noise, material textures, shading.

Every texture is a function ``texture(st, xyz) -> rgb`` of the Gaussians'
surface coordinates ``st`` (n, 2) in metres (along the patch's two edges) and
world positions ``xyz`` (n, 3) in metres, returning albedo RGB (n, 3) float64
in [0, 1].  The pattern (plank tones, noise waves, ...) is drawn when a
texture is *made*, from the caller's generator; the per-Gaussian colour
variation comes from the texture's own generator at each evaluation, so a
scene built with the same calls in the same order is the same scene.

Shading is baked into the colours (3DGS scenes carry their lighting in the
SH coefficients): one directional light plus ambient, :func:`shade`.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

#: A texture: (st (n, 2) metres, xyz (n, 3) metres) -> albedo RGB (n, 3) in [0, 1].
Texture = Callable[[np.ndarray, np.ndarray], np.ndarray]

#: Unit direction towards the light (world, z up): high, from the front-right.
LIGHT_DIR = np.array([0.35, -0.45, 0.82]) / np.linalg.norm([0.35, -0.45, 0.82])
#: Shading factor = AMBIENT + DIFFUSE * max(0, n . LIGHT_DIR).
AMBIENT, DIFFUSE = 0.58, 0.42


class SmoothNoise:
    """Band-limited noise: a sum of random plane waves with zero mean and unit variance.

    dim: 2 or 3 (the coordinate dimension it is evaluated on).
    wavelengths: (shortest, longest) feature size in metres; amplitudes grow
    with the wavelength (a 1/f-like spectrum, large blotches dominate).
    """

    def __init__(self, rng: np.random.Generator, dim: int = 2, wavelengths=(0.3, 3.0), n_waves: int = 16):
        dirs = rng.normal(size=(n_waves, dim))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        lam = np.exp(rng.uniform(np.log(wavelengths[0]), np.log(wavelengths[1]), n_waves))
        self.k = dirs * (2.0 * np.pi / lam)[:, None]
        self.phase = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        amp = np.sqrt(lam)
        # A sine of amplitude a has variance a^2 / 2: normalise the sum to variance 1.
        self.amp = amp * np.sqrt(2.0 / np.sum(amp**2))

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """Noise at points p (n, dim) -> (n,) float64, std ~1."""
        return np.sin(np.asarray(p, np.float64) @ self.k.T + self.phase) @ self.amp


def jitter_colour(rgb: np.ndarray, rng: np.random.Generator, brightness: float, hue: float) -> np.ndarray:
    """Per-Gaussian colour variation: a multiplicative brightness factor exp(N(0, brightness))
    and an additive per-channel N(0, hue); rgb (n, 3) -> (n, 3) clipped to [0, 1]."""
    n = rgb.shape[0]
    out = rgb * np.exp(rng.normal(0.0, brightness, (n, 1))) + rng.normal(0.0, hue, (n, 3))
    return np.clip(out, 0.0, 1.0)


def mix(a, b, t: np.ndarray) -> np.ndarray:
    """Per-point linear blend of colours a and b ((3,) or (n, 3)) by t (n,) in [0, 1]."""
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)[:, None]
    return (1.0 - t) * np.asarray(a, np.float64) + t * np.asarray(b, np.float64)


def shade(rgb: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Bake the directional light into albedo rgb (n, 3) given unit normals (n, 3)."""
    lambert = np.clip(np.asarray(normals) @ LIGHT_DIR, 0.0, 1.0)
    return np.clip(rgb * (AMBIENT + DIFFUSE * lambert)[:, None], 0.0, 1.0)


# ---------------------------------------------------------------------------- materials


def flat(colour, rng: np.random.Generator, *, variation: float = 0.04, blotch: float = 0.05,
         wavelengths=(0.2, 1.5)) -> Texture:
    """A uniform material (paint, plastic, fabric): base colour, soft blotches of
    relative amplitude ``blotch``, per-Gaussian brightness noise ``variation``."""
    base = np.asarray(colour, np.float64)
    noise = SmoothNoise(rng, 3, wavelengths)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        rgb = base[None, :] * (1.0 + blotch * noise(xyz))[:, None]
        return jitter_colour(rgb, sub, variation, 0.006)

    return tex


def wood_planks(rng: np.random.Generator, *, tone=(0.55, 0.36, 0.2), plank_width: float = 0.14,
                plank_length: float = 1.6, along: int = 0) -> Texture:
    """Floorboards: planks ``plank_width`` wide running along surface axis ``along``
    (0: s, 1: t), staggered ends, per-plank tone, fine grain along the plank."""
    tone = np.asarray(tone, np.float64)
    n_planks = 512
    plank_tone = np.exp(rng.normal(0.0, 0.12, n_planks))
    plank_shift = rng.uniform(0.0, plank_length, n_planks)
    grain_phase = rng.uniform(0.0, 2 * np.pi, n_planks)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        a, b = st[:, along], st[:, 1 - along]
        row = np.floor(b / plank_width).astype(np.int64) % n_planks
        seg = np.floor((a + plank_shift[row]) / plank_length).astype(np.int64)
        seg_tone = np.exp(0.08 * np.sin(seg * 12.9898 + row * 78.233))
        grain = 0.06 * np.sin(a * 23.0 + 3.0 * np.sin(a * 2.1 + grain_phase[row]) + grain_phase[row])
        # Darker seams between planks (within 8 mm of a plank edge).
        seam = np.abs(b / plank_width - np.round(b / plank_width)) * plank_width < 0.008
        f = plank_tone[row] * seg_tone * (1.0 + grain) * np.where(seam, 0.7, 1.0)
        rgb = tone[None, :] * f[:, None]
        return jitter_colour(rgb, sub, 0.05, 0.01)

    return tex


def wall_paint(colour, rng: np.random.Generator, *, floor_z: float = 0.0) -> Texture:
    """Painted plaster: subtle blotches, and ambient occlusion darkening towards the floor."""
    base = flat(colour, rng, variation=0.012, blotch=0.025, wavelengths=(0.4, 3.0))

    def tex(st, xyz):
        ao = 1.0 - 0.22 * np.exp(-(xyz[:, 2] - floor_z) / 0.25)
        return np.clip(base(st, xyz) * ao[:, None], 0.0, 1.0)

    return tex


def rug(rng: np.random.Generator, size, *, colours=None) -> Texture:
    """A woven rug of ``size`` (s, t) metres: border bands and a diamond lattice in muted colours."""
    palette = np.asarray(colours if colours is not None else
                         [(0.72, 0.66, 0.56), (0.45, 0.40, 0.36), (0.60, 0.52, 0.44), (0.30, 0.28, 0.27)],
                         np.float64)
    size = np.asarray(size, np.float64)
    period = rng.uniform(0.28, 0.4)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        edge = np.minimum(np.minimum(st[:, 0], size[0] - st[:, 0]), np.minimum(st[:, 1], size[1] - st[:, 1]))
        c = st - size / 2
        diamond = (np.abs(c[:, 0] % period - period / 2) + np.abs(c[:, 1] % period - period / 2)) / period
        idx = np.where(edge < 0.08, 3, np.where(edge < 0.16, 1, np.where(diamond < 0.22, 2, 0)))
        rgb = palette[idx]
        return jitter_colour(rgb, sub, 0.06, 0.012)

    return tex


def fabric(colour, rng: np.random.Generator) -> Texture:
    """Upholstery: a fine woven cross-hatch on a base colour."""
    base = flat(colour, rng, variation=0.05, blotch=0.04, wavelengths=(0.15, 0.8))

    def tex(st, xyz):
        weave = 1.0 + 0.05 * np.sin(st[:, 0] * 180.0) * np.sin(st[:, 1] * 180.0)
        return np.clip(base(st, xyz) * weave[:, None], 0.0, 1.0)

    return tex


def books(rng: np.random.Generator, *, shelf_height: float = 0.38, board=(0.5, 0.38, 0.24)) -> Texture:
    """The front of a filled bookshelf: rows of spines of random width and muted colour,
    separated by shelf boards; s runs along the shelf, t up."""
    palette = np.array([(0.55, 0.2, 0.15), (0.2, 0.3, 0.22), (0.75, 0.7, 0.6), (0.3, 0.3, 0.35),
                        (0.6, 0.45, 0.2), (0.15, 0.15, 0.15), (0.5, 0.5, 0.45), (0.35, 0.22, 0.3)])
    n_rows, per_row = 16, 64
    widths = rng.uniform(0.02, 0.06, (n_rows, per_row))
    edges = np.cumsum(widths, axis=1)
    colour_idx = rng.integers(0, len(palette), (n_rows, per_row))
    heights = rng.uniform(0.6, 0.95, (n_rows, per_row))
    board = np.asarray(board, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        row = np.clip(np.floor(st[:, 1] / shelf_height).astype(np.int64), 0, n_rows - 1)
        within = st[:, 1] - row * shelf_height
        k = np.empty(len(st), np.int64)
        for r in np.unique(row):
            sel = row == r
            k[sel] = np.minimum(np.searchsorted(edges[r], st[sel, 0] % edges[r, -1]), per_row - 1)
        spine = palette[colour_idx[row, k]]
        gap = np.array([0.08, 0.06, 0.05])  # the dark back of the shelf above shorter books
        is_board = within < 0.025
        above_book = within > heights[row, k] * shelf_height
        rgb = np.where(is_board[:, None], board, np.where(above_book[:, None], gap, spine))
        return jitter_colour(rgb, sub, 0.05, 0.01)

    return tex


def painting(rng: np.random.Generator, size, *, frame=(0.12, 0.1, 0.08)) -> Texture:
    """A framed abstract painting of ``size`` (s, t) metres: smooth colour fields, dark frame."""
    size = np.asarray(size, np.float64)
    fields = [SmoothNoise(rng, 2, (0.1, 0.6)) for _ in range(3)]
    colours = rng.uniform(0.15, 0.9, (3, 3))
    frame = np.asarray(frame, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        w = np.stack([f(st) for f in fields], 1)
        w = np.exp(1.5 * w)
        w /= w.sum(1, keepdims=True)
        rgb = w @ colours
        edge = np.minimum(np.minimum(st[:, 0], size[0] - st[:, 0]), np.minimum(st[:, 1], size[1] - st[:, 1]))
        rgb = np.where((edge < 0.045)[:, None], frame, rgb)
        return jitter_colour(rgb, sub, 0.03, 0.01)

    return tex


def window(rng: np.random.Generator, size, *, panes=(2, 2)) -> Texture:
    """A bright window of ``size`` (s, t) metres: pale sky gradient, white frame and muntins."""
    size = np.asarray(size, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        sky = mix((0.86, 0.9, 0.94), (0.62, 0.74, 0.9), st[:, 1] / size[1])
        u = st / size * np.asarray(panes)
        bar = np.min(np.abs(u - np.round(u)) * size / np.asarray(panes), axis=1) < 0.03
        rgb = np.where(bar[:, None], np.array([0.93, 0.93, 0.9]), sky)
        return jitter_colour(rgb, sub, 0.02, 0.005)

    return tex


def grass(rng: np.random.Generator) -> Texture:
    """Lawn: green with lighter and yellower patches, scattered bare soil, strong per-blade noise."""
    patch = SmoothNoise(rng, 2, (0.5, 4.0))
    dry = SmoothNoise(rng, 2, (1.0, 6.0))
    soil = SmoothNoise(rng, 2, (0.2, 1.2))
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        p = xyz[:, :2]
        rgb = mix((0.22, 0.38, 0.12), (0.36, 0.5, 0.17), 0.5 + 0.35 * patch(p))
        rgb = mix(rgb, (0.52, 0.5, 0.25), np.clip(dry(p) - 0.6, 0.0, 1.0))
        rgb = mix(rgb, (0.38, 0.3, 0.2), np.clip(2.0 * (soil(p) - 1.4), 0.0, 1.0))
        return jitter_colour(rgb, sub, 0.16, 0.02)

    return tex


def soil(rng: np.random.Generator) -> Texture:
    """Bare earth."""
    return flat((0.36, 0.28, 0.2), rng, variation=0.12, blotch=0.12, wavelengths=(0.1, 1.0))


def paving(rng: np.random.Generator, *, tile: float = 0.5) -> Texture:
    """Stone paving slabs of ``tile`` metres with dark joints and per-slab tone."""
    tones = np.exp(rng.normal(0.0, 0.08, (64, 64)))
    speckle = SmoothNoise(rng, 2, (0.05, 0.3))
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        cell = np.floor(st / tile).astype(np.int64) % 64
        f = tones[cell[:, 0], cell[:, 1]] * (1.0 + 0.05 * speckle(st))
        joint = np.min(np.abs(st / tile - np.round(st / tile)), axis=1) * tile < 0.012
        rgb = np.array([0.62, 0.6, 0.56])[None, :] * f[:, None]
        rgb = np.where(joint[:, None], np.array([0.3, 0.29, 0.27]), rgb)
        return jitter_colour(rgb, sub, 0.05, 0.01)

    return tex


def bark(rng: np.random.Generator) -> Texture:
    """Tree bark: dark brown with vertical furrows (s runs around the trunk, t up)."""
    sub = np.random.default_rng(rng.integers(2**63))
    phase = rng.uniform(0, 2 * np.pi)

    def tex(st, xyz):
        furrow = 0.5 + 0.5 * np.sin(st[:, 0] * 60.0 + 2.0 * np.sin(st[:, 1] * 3.0 + phase))
        rgb = mix((0.2, 0.15, 0.1), (0.36, 0.28, 0.2), furrow)
        return jitter_colour(rgb, sub, 0.1, 0.01)

    return tex


def foliage(rng: np.random.Generator, *, colour=(0.2, 0.36, 0.12)) -> Texture:
    """Leaves: green with lighter and darker clusters and strong per-leaf variation."""
    cluster = SmoothNoise(rng, 3, (0.15, 0.8))
    base = np.asarray(colour, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        f = np.exp(0.22 * cluster(xyz))
        rgb = base[None, :] * f[:, None]
        rgb[:, 0] += 0.04 * np.clip(cluster(xyz * 1.7 + 3.1), 0, None)  # a hint of yellow on some leaves
        return jitter_colour(rgb, sub, 0.2, 0.025)

    return tex


def sky(rng: np.random.Generator, centre) -> Texture:
    """Sky on a dome around ``centre``: pale at the horizon, blue at the zenith, soft clouds."""
    clouds = SmoothNoise(rng, 3, (4.0, 30.0))
    centre = np.asarray(centre, np.float64)

    def tex(st, xyz):
        d = xyz - centre
        elev = np.clip(d[:, 2] / np.linalg.norm(d, axis=1), 0.0, 1.0)
        rgb = mix((0.82, 0.87, 0.92), (0.36, 0.55, 0.84), elev**0.6)
        rgb = mix(rgb, (0.95, 0.95, 0.96), np.clip(clouds(d) - 0.4, 0.0, 1.0) * 0.8)
        return rgb

    return tex


def flowers(rng: np.random.Generator, *, colours=((0.85, 0.3, 0.45), (0.95, 0.8, 0.25), (0.9, 0.9, 0.88)),
            fraction: float = 0.35) -> Texture:
    """Flowering plant: foliage with ``fraction`` of the Gaussians in flower colours."""
    leaves = foliage(rng, colour=(0.2, 0.38, 0.14))
    palette = np.asarray(colours, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        rgb = leaves(st, xyz)
        bloom = sub.random(len(st)) < fraction
        rgb[bloom] = jitter_colour(palette[sub.integers(0, len(palette), int(bloom.sum()))], sub, 0.08, 0.02)
        return rgb

    return tex


def bricks(rng: np.random.Generator, *, colour=(0.58, 0.3, 0.22), brick=(0.3, 0.1),
           mortar=(0.72, 0.7, 0.64)) -> Texture:
    """Brickwork in stretcher bond: ``brick`` (length, height) metres, 1.5 cm mortar joints,
    per-brick tone; s runs along the wall, t up."""
    tones = np.exp(rng.normal(0.0, 0.12, (128, 128)))
    base, mortar = np.asarray(colour, np.float64), np.asarray(mortar, np.float64)
    sub = np.random.default_rng(rng.integers(2**63))

    def tex(st, xyz):
        row = np.floor(st[:, 1] / brick[1]).astype(np.int64)
        s = st[:, 0] + 0.5 * brick[0] * (row % 2)
        col = np.floor(s / brick[0]).astype(np.int64)
        joint = ((s - col * brick[0]) < 0.015) | ((st[:, 1] - row * brick[1]) < 0.015)
        rgb = base[None, :] * tones[row % 128, col % 128][:, None]
        rgb = np.where(joint[:, None], mortar, rgb)
        return jitter_colour(rgb, sub, 0.05, 0.01)

    return tex
