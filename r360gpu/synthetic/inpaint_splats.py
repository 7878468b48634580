"""A 360-USID-shaped scene backed by splats: the methods given as splat files, rendered at the test cameras.

`write_usid_splat_example` builds a demo scene (`r360gpu.synthetic.bundle.make_scene`) and
writes it as 360-USID ships a scene, with the methods as the splat files a trainer leaves::

    OUT/data/SCENE/sparse/0/{cameras,images,points3D}.bin   every camera, training and test (PINHOLE)
    OUT/data/SCENE/images/IMG_<i>.jpg          training photographs: pre (the object there) rendered
    OUT/data/SCENE/test_images/IMG_<i>.jpg     test photographs: the reference (no object) rendered
    OUT/output/SCENE/pre.ply                   the reconstruction with the object
    OUT/output/SCENE/reference.ply             the reconstruction without it (scores as the photographs)
    OUT/output/SCENE/<method>.ply              simulated removals (`r360gpu.synthetic.methods`)
    OUT/output/SCENE/object_mask/<i>.png       the target's masks at the test views (0 / 255)
    OUT/output/SCENE/target.npy                the target's Gaussians in pre.ply (indices, int64)

Training and test cameras alternate around the scene, so the test views are not the training
ones, as in 360-USID.  The photographs are JPEGs (the script globs ``test_images/*jpg``).
"""
from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import save_colmap, save_ply
from ..render.sources import SceneSource
from .bundle import encode_mask, make_method, make_scene
from .inpaint_folders import save_image, written_in_place
from .masks import target_masks

#: Marker of a folder written here (a folder holding it may be replaced).
MARKER = "r360-inpaint-splats.json"
#: The simulated removals written as methods.
SPLAT_METHODS = ("clean", "hole")


def write_usid_splat_example(out: str | os.PathLike, *, scene: str = "room", n_test: int = 3, n_train: int = 3,
                             width: int = 64, height: int = 48, detail: float = 0.05, seed: int = 0,
                             ctx=None) -> Path:
    """Write the layout of the module docstring under ``out`` (replacing an earlier one); returns ``out``."""
    out = Path(out)
    if n_test < 1 or n_train < 0:
        raise InputError(f"the example needs n_test >= 1 and n_train >= 0, got {n_test} and {n_train}")
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / MARKER).is_file())):
        raise InputError(f"exists and is not an example folder written by r360gpu (no {MARKER}); give a new folder",
                         out)
    s = make_scene(scene, seed=seed, n_views=n_test + n_train, width=width, height=height, detail=detail)
    cams = [replace(c, name=f"IMG_{i}.jpg") for i, c in enumerate(s.cameras)]
    test = cams[::2][:n_test]
    train = [c for c in cams if c not in test]

    def write(tmp: Path) -> None:
        data, output = tmp / "data" / s.name, tmp / "output" / s.name
        save_colmap(data / "sparse" / "0", cams)
        for folder, g, views in (("test_images", s.background, test), ("images", s.pre, train)):
            src = SceneSource(g, ctx=ctx)
            try:
                for c in views:
                    save_image(data / folder / c.name, src.images(c.name, c).rgb)
            finally:
                src.release()
        output.mkdir(parents=True)
        save_ply(output / "pre.ply", s.pre)
        save_ply(output / "reference.ply", s.background)
        np.save(output / "target.npy", np.arange(s.background.n, s.pre.n, dtype=np.int64))
        for m in SPLAT_METHODS:
            save_ply(output / f"{m}.ply", make_method(s, m, seed=seed))
        masks = target_masks(s, ctx=ctx, cameras=test)
        (output / "object_mask").mkdir()
        for k, c in enumerate(test):
            (output / "object_mask" / f"{k:05d}.png").write_bytes(encode_mask(np.asarray(masks[c.name])))
        (tmp / MARKER).write_text(json.dumps({"scene": s.name, "n_test": n_test, "n_train": n_train,
                                              "width": width, "height": height, "seed": seed}) + "\n")

    written_in_place(out, write)
    return out
