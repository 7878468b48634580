"""The indoor scene: a living room whose sofa is removed (prompt "sofa").

Layout (metres, z up): a 6.8 x 5.6 m room, 2.6 m high, wooden floor and
painted walls (the shell).  The sofa stands 0.8 m in front of the back wall
(y = 2.8), facing -y.  Around it: a rug under its front, a coffee table in
front, a floor lamp and a side table beside it (the neighbours an over-eager
removal takes along), a bookshelf, a potted plant that blocks the line of
sight of a few views, a painting and a window.  The cameras walk a 180
degree arc in front of the sofa.

Colours of the sofa, walls and floor are drawn from small palettes by the
seed; positions are jittered by a few centimetres.
"""
from __future__ import annotations

import numpy as np

from . import texture as tx
from .cameras import Rig
from .primitives import Part, Solid, blob, box, cylinder, surface
from .scene import SyntheticScene, build_scene

ROOM_X, ROOM_Y, ROOM_H = 3.4, 2.8, 2.6
SOFA_COLOURS = [(0.16, 0.25, 0.5), (0.45, 0.1, 0.14), (0.08, 0.38, 0.4)]
PILLOW_COLOURS = [(0.78, 0.56, 0.12), (0.85, 0.42, 0.3)]
WALL_COLOURS = [(0.85, 0.83, 0.78), (0.74, 0.77, 0.71), (0.79, 0.75, 0.69)]
FLOOR_TONES = [(0.55, 0.36, 0.2), (0.62, 0.47, 0.3), (0.42, 0.27, 0.16)]


def make_room(rng: np.random.Generator, *, n_views: int = 20, width: int = 480, height: int = 360,
              detail: float = 1.0) -> SyntheticScene:
    """Build the room scene; ``detail`` scales the number of Gaussians (1.0: about 55k)."""
    k = 1.0 / np.sqrt(detail)
    pick = lambda options: options[int(rng.integers(len(options)))]  # noqa: E731
    sofa_colour, pillow_colour = np.array(pick(SOFA_COLOURS)), pick(PILLOW_COLOURS)
    wall_colour, floor_tone = pick(WALL_COLOURS), pick(FLOOR_TONES)
    jx, jy = rng.uniform(-0.1, 0.1, 2)
    sofa_c = np.array([jx, 2.0 + 0.5 * jy])

    # ---- the target: a three-seat sofa --------------------------------------------------
    s = 0.025 * k
    fabric = tx.fabric(sofa_colour, rng)
    cushion = tx.fabric(np.clip(sofa_colour * 1.15 + 0.03, 0, 1), rng)
    pillow = tx.fabric(pillow_colour, rng)
    pieces = [  # (name, centre xyz, size, texture, yaw)
        ("base", (0.0, 0.0, 0.21), (2.0, 0.9, 0.42), fabric, 0.0),
        ("back", (0.0, 0.35, 0.63), (2.0, 0.2, 0.42), fabric, 0.0),
        ("arm", (-0.9, -0.05, 0.53), (0.2, 0.8, 0.22), fabric, 0.0),
        ("arm", (0.9, -0.05, 0.53), (0.2, 0.8, 0.22), fabric, 0.0),
        ("cushion", (-0.395, -0.1, 0.48), (0.78, 0.68, 0.12), cushion, 0.0),
        ("cushion", (0.395, -0.1, 0.48), (0.78, 0.68, 0.12), cushion, 0.0),
        ("pillow", (-0.58, 0.17, 0.7), (0.4, 0.12, 0.34), pillow, 0.18),
        ("pillow", (0.58, 0.17, 0.7), (0.4, 0.12, 0.34), pillow, -0.18),
    ]
    target, solids = [], []
    for name, c, size, tex, yaw in pieces:
        centre = (sofa_c[0] + c[0], sofa_c[1] + c[1], c[2])
        target.append(box(f"sofa-{name}", centre, size, s, tex, rng, yaw=yaw))
        solids.append(Solid(centre, size, yaw))

    # ---- the shell: floor, walls, baseboards ---------------------------------------------
    bg: list[Part] = []
    bg.append(surface("floor", (-ROOM_X, -ROOM_Y, 0.0), (2 * ROOM_X, 0, 0), (0, 2 * ROOM_Y, 0), 0.05 * k,
                      tx.wood_planks(rng, tone=floor_tone), rng, shell=True))
    paint = tx.wall_paint(wall_colour, rng)
    walls = [  # origin, u, v: normals point into the room
        ((-ROOM_X, ROOM_Y, 0.0), (2 * ROOM_X, 0, 0)),
        ((ROOM_X, -ROOM_Y, 0.0), (-2 * ROOM_X, 0, 0)),
        ((-ROOM_X, -ROOM_Y, 0.0), (0, 2 * ROOM_Y, 0)),
        ((ROOM_X, ROOM_Y, 0.0), (0, -2 * ROOM_Y, 0)),
    ]
    board = tx.flat((0.9, 0.89, 0.86), rng, variation=0.02, blotch=0.01)
    for origin, u in walls:
        bg.append(surface("wall", origin, u, (0, 0, ROOM_H), 0.07 * k, paint, rng, shell=True))
        normal = np.cross(np.asarray(u, float), [0.0, 0.0, 1.0])
        normal /= np.linalg.norm(normal)
        bg.append(surface("wall", np.asarray(origin) + 0.012 * normal, u, (0, 0, 0.09), 0.03 * k, board, rng,
                          shell=True))

    # ---- furniture and decoration ------------------------------------------------------
    bg.append(surface("rug", (sofa_c[0] - 1.4, sofa_c[1] - 1.8, 0.006), (2.8, 0, 0), (0, 2.0, 0), 0.04 * k,
                      tx.rug(rng, (2.8, 2.0)), rng))
    table_c = sofa_c + [0.0, -1.1]
    wood = tx.wood_planks(rng, tone=(0.35, 0.22, 0.13), plank_width=0.15)
    bg.append(box("coffee-table", (*table_c, 0.43), (1.1, 0.6, 0.04), 0.03 * k, wood, rng))
    for dx in (-0.5, 0.5):
        for dy in (-0.25, 0.25):
            bg.append(cylinder("coffee-table", (table_c[0] + dx, table_c[1] + dy, 0.0), 0.025, 0.41, 0.02 * k,
                               wood, rng, top=False))
    bg.append(box("coffee-table", (table_c[0] - 0.25, table_c[1] + 0.05, 0.475), (0.24, 0.17, 0.05), 0.02 * k,
                  tx.flat((0.7, 0.22, 0.18), rng), rng, yaw=0.3))
    bg.append(cylinder("coffee-table", (table_c[0] + 0.3, table_c[1] - 0.1, 0.45), 0.045, 0.1, 0.015 * k,
                       tx.flat((0.9, 0.9, 0.88), rng), rng))

    lamp = sofa_c + [1.4, 0.4]
    brass = tx.flat((0.55, 0.45, 0.25), rng, variation=0.03)
    bg.append(cylinder("lamp", (*lamp, 0.0), 0.16, 0.03, 0.03 * k, brass, rng))
    bg.append(cylinder("lamp", (*lamp, 0.03), 0.015, 1.35, 0.015 * k, brass, rng, top=False))
    bg.append(cylinder("lamp", (*lamp, 1.35), 0.22, 0.3, 0.03 * k, tx.flat((0.97, 0.9, 0.72), rng), rng,
                       taper=0.3))

    side = sofa_c + [-1.45, 0.25]
    bg.append(box("side-table", (*side, 0.275), (0.45, 0.45, 0.55), 0.03 * k,
                  tx.wood_planks(rng, tone=(0.45, 0.3, 0.18), plank_width=0.1), rng))
    bg.append(cylinder("side-table", (*side, 0.55), 0.07, 0.25, 0.015 * k, tx.flat((0.3, 0.45, 0.55), rng), rng,
                       taper=-0.3))

    shelf_tex = tx.wood_planks(rng, tone=(0.5, 0.38, 0.24), plank_width=0.2, along=1)
    bg.append(box("bookshelf", (-ROOM_X + 0.2, 0.6, 0.95), (0.36, 1.5, 1.9), 0.035 * k,
                  {"+x": tx.books(rng), "+z": shelf_tex, "+y": shelf_tex, "-y": shelf_tex, "-x": shelf_tex},
                  rng, yaw=0.0, faces=("+x", "+z", "+y", "-y")))

    plant = sofa_c + [-1.35, -0.6]
    bg.append(cylinder("plant", (*plant, 0.0), 0.15, 0.32, 0.025 * k, tx.flat((0.62, 0.33, 0.2), rng), rng,
                       taper=-0.2))
    bg.append(blob("plant", (*plant, 0.76), (0.28, 0.28, 0.4), 0.04 * k, tx.foliage(rng), rng))

    bg.append(surface("painting", (sofa_c[0] - 0.7, ROOM_Y - 0.015, 1.25), (1.4, 0, 0), (0, 0, 0.7), 0.025 * k,
                      tx.painting(rng, (1.4, 0.7)), rng))
    bg.append(surface("window", (ROOM_X - 0.015, 0.8, 0.9), (0, -2.0, 0), (0, 0, 1.3), 0.04 * k,
                      tx.window(rng, (2.0, 1.3)), rng))

    neighbourhood = Solid((sofa_c[0], sofa_c[1], 0.75), (3.1, 2.0, 1.5))
    rig = Rig(target=(sofa_c[0], sofa_c[1], 0.42), front=-np.pi / 2, arc=np.deg2rad(180.0),
              radius=(2.2, 2.65), height=(1.25, 1.7))
    return build_scene("room", "sofa", bg, target, solids, neighbourhood, rig, n_views=n_views, width=width,
                       height=height, rng=rng)
