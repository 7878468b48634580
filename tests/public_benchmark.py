"""A benchmark root in the public Remove360 layout, made from the synthetic scenes: ROOT/<method>/<scene>/.

Every method folder holds that method's OWN pre-removal renders (``rgb/before``,
``depth/before``), as every real pipeline trains and renders its own scene
before removing, next to its post-removal renders (``rgb/after``,
``depth/after``), the dataset's ``masks/`` and ``prompt.txt``.  The three
methods (names as in the paper's tables) differ both in their removal and in
their pre-removal reconstruction:

* ``GC``: pre retrained (small noise on positions, scales, colours); removal "clean";
* ``AF``: pre retrained with the target's colours washed out 40% towards grey
  (a weaker reconstruction of the object); removal "floaters";
* ``OC``: pre = the original scene; removal "recoloured".

Depth is written as 16-bit PNG in millimetres (``depth/...``), the unit the
renders of one folder share, which is all the per-view GHT threshold needs.

    python tests/public_benchmark.py OUT [--views N] [--width W] [--height H] [--skip AF/garden]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

METHODS = {"GC": "clean", "AF": "floaters", "OC": "recoloured"}


def _own_pre(scene, method: str, rng):
    from r360gpu.io import Gaussians
    from r360gpu.synthetic.primitives import rgb_to_sh, sh_to_rgb
    from r360gpu.synthetic.methods import retrained

    if method == "OC":
        return scene.pre
    g = retrained(scene.pre, rng)
    if method == "AF":
        sh = np.array(g.sh, np.float64)
        target = np.arange(g.n) >= scene.background.n  # pre = background then target
        rgb = sh_to_rgb(sh[target])
        sh[target, 0, :] = rgb_to_sh(0.6 * rgb + 0.4 * 0.5)[:, 0, :]
        g = Gaussians(means=g.means, scales=g.scales, quats=g.quats, opacities=g.opacities, sh=sh)
    return g


def _write_renders(folder: Path, which: str, gaussians, cameras, ctx) -> None:
    from r360gpu.render import Renderer

    (folder / "rgb" / which).mkdir(parents=True, exist_ok=True)
    (folder / "depth" / which).mkdir(parents=True, exist_ok=True)
    r = Renderer(gaussians, ctx=ctx)
    try:
        for cam in cameras:
            out = r.render(cam)
            rgb = (np.clip(out.rgb, 0, 1) * 255 + 0.5).astype(np.uint8)
            cv2.imwrite(str(folder / "rgb" / which / f"{cam.name}.png"), rgb[:, :, ::-1])
            mm = np.clip(np.nan_to_num(out.depth, nan=0.0, posinf=0.0) * 1000 + 0.5, 0, 65535).astype(np.uint16)
            cv2.imwrite(str(folder / "depth" / which / f"{cam.name}.png"), mm)
    finally:
        r.release()


def make_public_benchmark(root, *, scenes=("room", "garden"), n_views: int = 8, width: int = 320,
                          height: int = 240, detail: float = 0.5, seed: int = 0, skip=(), ctx=None) -> Path:
    """Write ROOT/<method>/<scene>/ for the three methods and the given synthetic scenes; ``skip`` lists
    "METHOD/scene" folders to leave out (a method missing from a scene)."""
    from r360gpu.gpu import get_context
    from r360gpu.synthetic import make_scene
    from r360gpu.synthetic.bundle import _rng, encode_mask, make_method
    from r360gpu.synthetic.masks import target_masks

    ctx = ctx or get_context()
    root = Path(root)
    for name in scenes:
        scene = make_scene(name, seed=seed, n_views=n_views, width=width, height=height, detail=detail)
        masks = target_masks(scene, ctx=ctx)
        for method, edit in METHODS.items():
            if f"{method}/{name}" in skip:
                continue
            folder = root / method / name
            (folder / "masks").mkdir(parents=True, exist_ok=True)
            for view, m in masks.items():
                (folder / "masks" / f"{view}.png").write_bytes(encode_mask(m))
            (folder / "prompt.txt").write_text(scene.prompt + "\n", encoding="utf-8")
            _write_renders(folder, "before", _own_pre(scene, method, _rng(seed, "pre", name, method)),
                           scene.cameras, ctx)
            _write_renders(folder, "after", make_method(scene, edit, seed=seed), scene.cameras, ctx)
    return root


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--skip", action="append", default=[], metavar="METHOD/SCENE")
    a = ap.parse_args()
    make_public_benchmark(a.out, n_views=a.views, width=a.width, height=a.height, skip=a.skip)
    print(f"wrote {a.out}/<method>/<scene>/ for methods {', '.join(METHODS)}")


if __name__ == "__main__":
    main()
