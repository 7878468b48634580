"""``--frame``: the world frame of the splat scenes, for ``score`` and ``check`` alike.

The command-line form of scene.toml's top-level ``frame`` key (docs/your-scene.md): it
replaces that key for every bundle given; a source's own ``frame`` key still wins.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_frame_option(p) -> None:
    from ..io.frames import FRAME_KEYWORDS

    p.add_argument("--frame", type=frame_value, default=None, metavar="FRAME",
                   help=f"world frame of the splat scenes, as scene.toml's frame key (replaces it; a source's own "
                        f"frame key still wins): {', '.join(FRAME_KEYWORDS)}, or the path of a nerfstudio "
                        f"dataparser_transforms.json. 'gsplat' recomputes gsplat simple_trainer's "
                        f"normalize_world_space from the COLMAP cameras and points3D")


def frame_value(value: str) -> str:
    """A ``--frame`` value: a keyword as it is, a file as its absolute path (scene.toml paths are
    relative to the bundle, a command line's to the current folder)."""
    from ..io.frames import FRAME_KEYWORDS

    if value in FRAME_KEYWORDS:
        return value
    if Path(value).is_file():
        return str(Path(value).resolve())
    raise argparse.ArgumentTypeError(
        f"{value!r} is neither one of {', '.join(FRAME_KEYWORDS)} nor an existing file (a nerfstudio "
        f"dataparser_transforms.json)")
