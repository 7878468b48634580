"""The outdoor scene: a garden whose bench is removed (prompt "bench").

Layout (metres, z up): a lawn (flat near the bench, gently rolling further
out) inside a hedge, trees beyond it and a sky dome (the shell).  A painted
storage bench (solid box seat, slatted backrest, armrests) stands on a
stone patio, facing -y, with flower pots on both sides (the neighbours an
over-eager removal takes along).  A tree close to the patio blocks the line
of sight of a few views; bushes dot the lawn.  The cameras walk a 150 degree
arc in front of the bench.

The bench colour is drawn from a small palette by the seed; positions are
jittered by a few centimetres.

``garden_open`` (:func:`make_garden_open`) is the same garden without the
patio wall behind the bench: the bench stands in open space, so cameras all
around it see its far side, which the capture never faces (the proof that
``score --orbit`` catches what the capture misses, the ``backside`` method).
"""
from __future__ import annotations

import numpy as np

from . import texture as tx
from .cameras import Rig
from .primitives import Part, Solid, blob, box, cylinder, dome, heightfield, surface
from .scene import SyntheticScene, build_scene

BENCH_COLOURS = [(0.6, 0.17, 0.13), (0.17, 0.28, 0.55), (0.78, 0.6, 0.16)]
#: The hedge encloses |x| <= GARDEN_X, y <= GARDEN_Y; the lawn is modelled out to GROUND.
GARDEN_X, GARDEN_Y, GROUND = 7.0, 6.0, 7.5
PATIO = ((-1.8, 1.8), (-1.4, 0.63))


def _terrain(rng: np.random.Generator):
    """Height function: flat within 2.5 m of the bench, rolling by up to ~0.25 m beyond 6 m."""
    hills = tx.SmoothNoise(rng, 2, (3.0, 12.0), n_waves=8)

    def height(x, y):
        r = np.hypot(x, y)
        ramp = np.clip((r - 2.5) / 3.5, 0.0, 1.0)
        return 0.12 * ramp**2 * hills(np.stack([x, y], 1))

    return height


def _tree(name: str, base, trunk_height: float, crown, rng: np.random.Generator, k: float,
          shell: bool) -> list[Part]:
    bx, by, bz = base
    rx, ry, rz = crown
    trunk = cylinder(name, base, 0.13, trunk_height + 0.4 * rz, 0.04 * k, tx.bark(rng), rng, taper=0.35,
                     top=False, shell=shell)
    leaves = blob(name, (bx, by, bz + trunk_height + 0.8 * rz), crown, 0.11 * k, tx.foliage(rng), rng,
                  shell=shell)
    return [trunk, leaves]


def make_garden(rng: np.random.Generator, *, n_views: int = 20, width: int = 480, height: int = 360,
                detail: float = 1.0, open_space: bool = False) -> SyntheticScene:
    """Build the garden scene; ``detail`` scales the number of Gaussians (1.0: about 60k).

    open_space: leave out the patio wall behind the bench (the ``garden_open`` scene).
    """
    k = 1.0 / np.sqrt(detail)
    bench_colour = np.array(BENCH_COLOURS[int(rng.integers(len(BENCH_COLOURS)))])
    jx, jy = rng.uniform(-0.08, 0.08, 2)
    c = np.array([jx, jy])

    # ---- the target: a painted storage bench --------------------------------------------
    s = 0.022 * k
    panels = tx.wood_planks(rng, tone=bench_colour, plank_width=0.11, plank_length=5.0, along=1)
    lid = tx.wood_planks(rng, tone=np.clip(bench_colour * 0.85, 0, 1), plank_width=0.14, plank_length=5.0)
    slats = tx.wood_planks(rng, tone=np.clip(bench_colour * 1.1 + 0.03, 0, 1), plank_width=0.2, plank_length=5.0)
    pieces = [  # (name, centre xyz relative to the bench, size, texture, faces)
        ("base", (0.0, 0.0, 0.215), (1.5, 0.5, 0.43), panels, None),
        ("lid", (0.0, -0.01, 0.45), (1.58, 0.56, 0.04), lid, ("+z", "-z", "+x", "-x", "+y", "-y")),
        ("slat", (0.0, 0.23, 0.6), (1.5, 0.035, 0.08), slats, None),
        ("slat", (0.0, 0.23, 0.72), (1.5, 0.035, 0.08), slats, None),
        ("slat", (0.0, 0.23, 0.84), (1.5, 0.035, 0.08), slats, None),
        ("post", (-0.76, 0.23, 0.67), (0.06, 0.05, 0.44), lid, None),
        ("post", (0.76, 0.23, 0.67), (0.06, 0.05, 0.44), lid, None),
        ("arm", (-0.76, 0.0, 0.65), (0.06, 0.5, 0.04), lid, None),
        ("arm", (0.76, 0.0, 0.65), (0.06, 0.5, 0.04), lid, None),
        ("arm-post", (-0.76, -0.22, 0.55), (0.05, 0.05, 0.16), lid, None),
        ("arm-post", (0.76, -0.22, 0.55), (0.05, 0.05, 0.16), lid, None),
    ]
    target, solids = [], []
    for name, rel, size, tex, faces in pieces:
        centre = (c[0] + rel[0], c[1] + rel[1], rel[2])
        kwargs = {"faces": faces} if faces else {}
        target.append(box(f"bench-{name}", centre, size, s, tex, rng, **kwargs))
        solids.append(Solid(centre, size))

    # ---- the shell: lawn, hedge, trees beyond, sky --------------------------------------
    bg: list[Part] = []
    height_fn = _terrain(rng)
    lawn = tx.grass(rng)
    inner = ((-3.5, 3.5), (-3.5, 3.5))
    bg.append(heightfield("lawn", *inner, 0.065 * k, height_fn, lawn, rng))
    bg.append(heightfield("lawn", (-GROUND, GROUND), (-GROUND, GROUND), 0.16 * k, height_fn, lawn, rng,
                          exclude=inner))
    hedge = tx.foliage(rng, colour=(0.13, 0.27, 0.1))
    for centre, size in (((0.0, GARDEN_Y + 0.45, 0.8), (2 * GARDEN_X + 1.8, 0.9, 1.6)),
                         ((-GARDEN_X - 0.45, 0.0, 0.8), (0.9, 2 * GROUND, 1.6)),
                         ((GARDEN_X + 0.45, 0.0, 0.8), (0.9, 2 * GROUND, 1.6))):
        bg.append(box("hedge", centre, size, 0.13 * k, hedge, rng, bump=0.03, shell=True))
    for i, (x, y) in enumerate(((-6.0, 9.5), (-2.0, 11.0), (2.5, 10.0), (6.5, 9.0), (-9.5, 3.0), (10.0, 2.0))):
        crown = rng.uniform(1.6, 2.4, 3) * [1.0, 1.0, 0.9]
        bg.extend(_tree("far-trees", (x, y, 0.0), rng.uniform(1.8, 2.6), crown, rng, 2.0 * k, True))
    bg.append(dome("sky", (0.0, 0.0, 0.0), 30.0, 2.2, tx.sky(rng, (0.0, 0.0, 0.0)), rng, min_elevation=-0.2))

    # ---- garden furniture and plants ----------------------------------------------------
    (px0, px1), (py0, py1) = PATIO
    bg.append(surface("patio", (c[0] + px0, c[1] + py0, 0.012), (px1 - px0, 0, 0), (0, py1 - py0, 0), 0.045 * k,
                      tx.paving(rng), rng))
    if not open_space:
        brick = tx.bricks(rng)
        bg.append(box("garden-wall", (c[0], c[1] + 0.75, 0.6), (3.6, 0.24, 1.2), 0.035 * k, brick, rng,
                      shell=True))
        bg.append(box("garden-wall", (c[0], c[1] + 0.75, 1.225), (3.7, 0.3, 0.05), 0.03 * k,
                      tx.flat((0.7, 0.68, 0.62), rng), rng, shell=True))
    pot = tx.flat((0.66, 0.36, 0.22), rng, variation=0.05)
    for dx in (-1.07, 1.07):
        base = (c[0] + dx, c[1] + 0.05, 0.012)
        bg.append(cylinder("flower-pot", base, 0.15, 0.3, 0.025 * k, pot, rng, taper=-0.25))
        bg.append(blob("flower-pot", (base[0], base[1], 0.42), (0.2, 0.2, 0.16), 0.03 * k, tx.flowers(rng), rng))
    bg.extend(_tree("tree", (c[0] - 1.6, c[1] - 1.0, 0.0), 1.9, (1.1, 1.1, 0.9), rng, k, False))
    for x, y, r in ((2.6, -1.6, 0.5), (-3.4, 1.8, 0.6), (3.2, 2.4, 0.55), (0.6, 3.6, 0.7)):
        bg.append(blob("bush", (x, y, 0.8 * r), (r, r, 0.8 * r), 0.06 * k, tx.foliage(rng, colour=(0.18, 0.33, 0.1)),
                       rng))

    neighbourhood = Solid((c[0], c[1], 0.7), (2.8, 1.8, 1.4))
    rig = Rig(target=(c[0], c[1], 0.45), front=-np.pi / 2, arc=np.deg2rad(120.0), radius=(2.5, 3.1),
              height=(1.3, 1.8))
    return build_scene("garden_open" if open_space else "garden", "bench", bg, target, solids, neighbourhood, rig,
                       n_views=n_views, width=width, height=height, rng=rng)


def make_garden_open(rng: np.random.Generator, *, n_views: int = 20, width: int = 480, height: int = 360,
                     detail: float = 1.0) -> SyntheticScene:
    """The garden without the patio wall: the bench in open space (see the module docstring)."""
    return make_garden(rng, n_views=n_views, width=width, height=height, detail=detail, open_space=True)
