"""Renders and lift weights identical before and after a change: snapshot them, compare two snapshots.

With the r360gpu that ``PYTHONPATH`` (or the installed package) gives, on the procedural scenes
(``room`` and ``garden`` at a quarter of their Gaussians, 4 views each at 160x120):

* every plane of :meth:`Renderer.render <r360gpu.render.Renderer.render>` (rgb, alpha, depth,
  median depth), with the default conventions and antialiased with a grey background, and with the
  sorts on the host and in WGSL (``R360GPU_SORT``);
* the lift weights of the target (:class:`~r360gpu.lift.MaskLifter`: the scene's own target masks,
  float shares, lifted to pre's Gaussians, per view and summed);
* the target masks rendered back from those Gaussians (`r360gpu.lift.target_masks`).

    python bench/render_lift_identical.py snapshot before.npz     # on the old tree
    python bench/render_lift_identical.py snapshot after.npz      # on the new tree
    python bench/render_lift_identical.py compare before.npz after.npz

``compare`` prints, per array, whether it is bit-equal (``np.array_equal`` on the raw arrays, and
the same dtype and shape), and exits 1 when any differs or is missing on one side.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

SCENES = ("room", "garden")
VIEWS, WIDTH, HEIGHT, DETAIL = 4, 160, 120, 0.25


def _render_arrays(scene, cameras, out: dict, tag: str) -> None:
    from r360gpu.render import Renderer, RenderOptions

    for opts, bg, name in ((RenderOptions(), (0.0, 0.0, 0.0), "default"),
                           (RenderOptions(antialiased=True), (0.5, 0.5, 0.5), "aa_grey")):
        renderer = Renderer(scene.pre, options=opts, background=bg)
        try:
            for cam in cameras:
                r = renderer.render(cam)
                for plane in ("rgb", "alpha", "depth", "median_depth"):
                    out[f"{tag}/render/{name}/{cam.name}/{plane}"] = getattr(r, plane)
        finally:
            renderer.release()


def _lift_arrays(scene, cameras, out: dict, tag: str) -> None:
    from r360gpu.lift import lift_target, target_masks

    is_target = np.zeros(scene.pre.n, bool)
    is_target[scene.background.n:] = True
    shares = [np.asarray(m, np.float32) for m in target_masks(scene.pre, is_target, cameras)]
    # float shares too: a soft edge exercises the mask's weighting, not only 0/1
    soft = [0.25 + 0.5 * m for m in shares]
    for name, masks in (("binary", shares), ("soft", soft)):
        lifted = lift_target(scene.pre, cameras, masks, per_view=True)
        out[f"{tag}/lift/{name}/w_in"] = lifted.w_in
        out[f"{tag}/lift/{name}/w_out"] = lifted.w_out
        out[f"{tag}/lift/{name}/w_views"] = lifted.w_views
        out[f"{tag}/lift/{name}/target"] = lifted.target
    for cam, m in zip(cameras, target_masks(scene.pre, lifted.target, cameras)):
        out[f"{tag}/target_mask/{cam.name}"] = np.asarray(m)


def snapshot(path: str) -> int:
    from r360gpu.synthetic import make_scene

    out: dict[str, np.ndarray] = {}
    for sort in ("cpu", "gpu"):
        os.environ["R360GPU_SORT"] = sort
        for name in SCENES:
            scene = make_scene(name, n_views=VIEWS, width=WIDTH, height=HEIGHT, detail=DETAIL)
            _render_arrays(scene, scene.cameras, out, f"{sort}/{name}")
            if sort == "cpu":  # lifting shares the renderer's sort; once is enough
                _lift_arrays(scene, scene.cameras, out, name)
    np.savez_compressed(path, **out)
    print(f"{len(out)} arrays -> {path} (r360gpu from {os.path.dirname(sys.modules['r360gpu'].__file__)})")
    return 0


def compare(before: str, after: str) -> int:
    a, b = np.load(before), np.load(after)
    bad = 0
    for key in sorted(set(a.files) | set(b.files)):
        if key not in a.files or key not in b.files:
            print(f"MISSING in {'before' if key not in a.files else 'after'}: {key}")
            bad += 1
            continue
        x, y = a[key], b[key]
        if x.dtype != y.dtype or x.shape != y.shape or not np.array_equal(x, y):
            diff = np.abs(x.astype(np.float64) - y.astype(np.float64)).max() if x.shape == y.shape else "shape"
            print(f"DIFFERS: {key} ({x.dtype}{x.shape} vs {y.dtype}{y.shape}; max |diff| {diff})")
            bad += 1
    print(f"{len(set(a.files) | set(b.files))} arrays compared: "
          + ("all bit-equal" if not bad else f"{bad} differ or are missing"))
    return 1 if bad else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("snapshot")
    s.add_argument("path")
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    args = ap.parse_args(argv)
    return snapshot(args.path) if args.cmd == "snapshot" else compare(args.before, args.after)


if __name__ == "__main__":
    raise SystemExit(main())
