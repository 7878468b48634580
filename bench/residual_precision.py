"""Residual Gaussians of the synthetic floaters method: precision at the floater count.

    python bench/residual_precision.py [--scenes room garden] [--seeds 0 1] [--work DIR]

For each scene and seed, a bundle with the methods ``clean`` and ``floaters``
(6 views, 240x180, detail 0.25) is generated, and the residuals of
:func:`r360gpu.pipeline.residuals.scene_residuals` are computed with every view
counted as flagging evidence, in three settings:

* ``reference``: the bundle as generated (a splat reference: the surface behind
  the object is the reference's);
* ``no reference, indices``: the reference dropped, the target given as the
  generator's own target Gaussians (``[target] indices``);
* ``no reference, masks``: the reference dropped, the target lifted from the
  bundle's masks.

The floaters method's Gaussians are the scene's background followed by the
floaters (the generator builds it so), so the floaters are the indices from the
background's count on.  Printed: the share of floaters among the floater-count
highest residuals (the goal: >= 0.9).
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from r360gpu.bundle import load_bundle  # noqa: E402
from r360gpu.lift import top_residuals  # noqa: E402
from r360gpu.pipeline.residuals import scene_residuals  # noqa: E402
from r360gpu.synthetic import generate_benchmark, make_scene  # noqa: E402

lift_residuals = importlib.import_module("r360gpu.lift.residuals")  # (r360gpu.lift exports a function of that name)
SIZE = dict(n_views=6, width=240, height=180, detail=0.25)


def precision(bundle, n_background: int) -> tuple[float, int]:
    """(precision at the floater count, floater count) of the floaters method's residuals."""
    every_view = lambda view_axes: list(bundle.views)  # noqa: E731
    real = lift_residuals.flagged_views
    lift_residuals.flagged_views = every_view
    try:
        _, values = scene_residuals(bundle, {m: {"views": []} for m in bundle.methods}, None)
    finally:
        lift_residuals.flagged_views = real
    r = values["floaters"]
    n_floaters = len(r) - n_background
    return float(np.mean(top_residuals(r, n_floaters) >= n_background)), n_floaters


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["room", "garden"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    ap.add_argument("--work", type=Path, default=None, help="where the bundles are generated (default: a temp folder)")
    args = ap.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="r360-residuals-"))
    print("| scene, seed | floaters | reference | no reference, indices | no reference, masks |")
    print("|---|---|---|---|---|")
    for name in args.scenes:
        for seed in args.seeds:
            root = work / f"{name}_{seed}"
            folder = generate_benchmark(root, scenes=(name,), methods=("clean", "floaters"), seed=seed, **SIZE)[0]
            scene = make_scene(name, seed=seed, **SIZE)
            n_bg = scene.background.n
            plain = load_bundle(folder)
            with_ref, nf = precision(plain, n_bg)
            np.save(root / "target.npy", np.arange(n_bg, scene.pre.n))
            toml = (folder / "scene.toml").read_text()
            (folder / "scene.toml").write_text(toml + f'\n[target]\nindices = "{(root / "target.npy").as_posix()}"\n')
            by_indices, _ = precision(dataclasses.replace(load_bundle(folder), reference=None), n_bg)
            (folder / "scene.toml").write_text(toml)
            by_masks, _ = precision(dataclasses.replace(load_bundle(folder), reference=None), n_bg)
            print(f"| {name}, {seed} | {nf} | {with_ref:.3f} | {by_indices:.3f} | {by_masks:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
