"""The built-in structural probe (method "hierarchy") on the demo's renderings: the probe against the plain
reference of its algorithm (``tests/structural_oracle.py``: every level as a label image, areas and first
pixels from every pixel of each level, one mask per comparison), timed image by image in the same run, with
the mask sets compared bit for bit.  Printed: CPU seconds of each (process time: OpenCV's threads
included), the ratio, and how many images gave identical sets; the graph segmentation both share is timed
on its own, as the floor neither can go under.

    python bench/bench_structural_probe.py [--views 4] [--width 480] [--height 360] [--scenes room garden]

The renderings: ``--views`` evaluation views of each scene of the demo's synthetic benchmark (generated in a
scratch folder), every source (pre, reference, each method) rendered at each.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import header  # noqa: E402


def demo_renderings(folder, scenes, n_views, width, height) -> list[np.ndarray]:
    """uint8 RGB renderings of every source of the demo scenes at ``n_views`` views each."""
    from r360gpu.bundle import load_bundle
    from r360gpu.gpu import get_context
    from r360gpu.io import load_gaussians
    from r360gpu.probes.builtin import as_rgb_uint8
    from r360gpu.render import Renderer
    from r360gpu.synthetic import generate_benchmark

    ctx = get_context()
    images = []
    for path in generate_benchmark(folder, n_views=n_views, width=width, height=height, scenes=scenes, ctx=ctx):
        b = load_bundle(path)
        sources = [b.pre.path, b.reference.path, *(m.path for m in b.methods.values())]
        for source in sources:
            r = Renderer(load_gaussians(source), ctx=ctx, background=b.options.background)
            images += [as_rgb_uint8(np.clip(r.render(b.cameras[v]).rgb, 0.0, 1.0)) for v in b.views]
    return images


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--views", type=int, default=4)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--scenes", nargs="+", default=["room", "garden"])
    args = ap.parse_args(argv)
    from structural_oracle import hierarchy_masks_oracle

    from r360gpu.probes.builtin import to_working, working_size
    from r360gpu.probes.builtin_structural import BuiltinStructuralProbe, StructuralParams, _graph_labels

    header("built-in structural probe (hierarchy): reference algorithm vs r360gpu, demo renderings")
    with tempfile.TemporaryDirectory() as tmp:
        images = demo_renderings(tmp, args.scenes, args.views, args.width, args.height)
    probe = BuiltinStructuralProbe()
    params = probe.config
    fine = StructuralParams(method="graph", sigma=params.sigma, k=params.fine_k, min_area_frac=params.fine_min_area_frac)
    t_ref = t_ours = t_graph = 0.0
    same, masks = 0, 0
    for image in images:
        size = image.shape[:2]
        work = to_working(image, working_size(size[0], size[1], int(params.work_long_side)))
        t = time.process_time()
        want = hierarchy_masks_oracle(work, params, size)
        t_ref += time.process_time() - t
        t = time.process_time()
        got = probe.predict_image(image).masks
        t_ours += time.process_time() - t
        t = time.process_time()
        _graph_labels(work, fine)
        t_graph += time.process_time() - t
        same += int(got.shape == want.shape and np.array_equal(got, want))
        masks += want.shape[0]
    n = len(images)
    print(f"{n} renderings {args.width}x{args.height}, {masks} masks in all")
    print(f"reference algorithm {t_ref:.2f} CPU-s ({1e3 * t_ref / n:.1f} ms/image)")
    print(f"r360gpu             {t_ours:.2f} CPU-s ({1e3 * t_ours / n:.1f} ms/image)")
    print(f"ratio reference/r360gpu {t_ref / t_ours:.2f}x; graph segmentation alone (in both) "
          f"{1e3 * t_graph / n:.1f} ms/image")
    print(f"identical mask sets: {same}/{n}")
    return 0 if same == n else 1


if __name__ == "__main__":
    sys.exit(main())
