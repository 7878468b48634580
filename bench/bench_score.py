"""End-to-end scoring speed: one synthetic scene, 150 views at 1920x1080, 3 methods,
precomputed probe masks (so the probes cost nothing and the pipeline is measured).

Prints seconds per stage (render, probe, measure, pictures) and views/s.

    python bench/bench_score.py [--views 150] [--width 1920] [--height 1080] [--out DIR] [--no-pictures]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np


def write_precomputed(bundle: Path, views, methods, out: Path) -> None:
    """Semantic PNG masks and SAM-style JSON mask sets for pre, ref and every method.

    The masks are derived from the target masks (the semantic probe "finds" the
    object on pre, half of it on floaters, all of it on recoloured, nothing on
    clean), so the axes stay meaningful while no probe model runs.
    """
    from r360gpu.io import load_mask
    from r360gpu.probes.rle import encode

    found = {"clean": 0.0, "floaters": 0.5, "recoloured": 1.0}
    for v in views:
        m = load_mask(bundle / "masks" / f"{v}.png")
        h, w = m.shape
        cols = np.flatnonzero(m.any(0))
        half = m.copy()
        if cols.size:
            half[:, cols[0] + cols.size // 2:] = False

        def save_png(path: Path, mask):
            path.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(path), (mask * 255).astype(np.uint8))

        def save_sam(path: Path, masks):
            path.parent.mkdir(parents=True, exist_ok=True)
            recs = []
            for mk in masks:
                rle = encode(mk)
                ys, xs = np.nonzero(mk)
                bbox = [int(xs.min()), int(ys.min()), int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1] if xs.size else [0, 0, 0, 0]
                recs.append({"segmentation": rle, "area": int(mk.sum()), "bbox": bbox})
            path.write_text(json.dumps(recs))

        ring = cv2.dilate(m.astype(np.uint8), np.ones((31, 31), np.uint8)).astype(bool) & ~m
        save_png(out / "sem" / "pre" / f"{v}.png", m)
        save_sam(out / "str" / "ref" / f"{v}.json", [ring])
        save_sam(out / "str" / "pre" / f"{v}.json", [m, ring])
        for meth in methods:
            k = found[meth]
            save_png(out / "sem" / "post" / meth / f"{v}.png", m if k == 1 else half if k else np.zeros_like(m))
            post_sets = {"clean": [ring], "floaters": [half, ring], "recoloured": [m, ring]}[meth]
            save_sam(out / "str" / "post" / meth / f"{v}.json", post_sets)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--views", type=int, default=150)
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--out", default=None, help="working folder (default: a temporary one)")
    ap.add_argument("--no-pictures", action="store_true")
    args = ap.parse_args()

    from r360gpu.gpu import get_context
    from r360gpu.probes.registry import parse_probe_spec
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import generate_benchmark

    ctx = get_context()
    d = ctx.describe()
    print(f"# scoring benchmark: {args.views} views at {args.width}x{args.height}, 3 methods, precomputed masks")
    print(f"adapter: {d['name']} ({d['adapter_type']}, {d['backend']})")
    work = Path(args.out or tempfile.mkdtemp(prefix="r360bench-"))
    methods = ["clean", "floaters", "recoloured"]
    t = time.perf_counter()
    bundle = generate_benchmark(work / "bench", n_views=args.views, width=args.width, height=args.height,
                                scenes=("room",), methods=methods, ctx=ctx)[0]
    t_gen = time.perf_counter() - t
    from r360gpu.bundle import load_bundle

    views = load_bundle(bundle).views
    t = time.perf_counter()
    write_precomputed(bundle, views, methods, work / "masks")
    t_masks = time.perf_counter() - t
    sem = parse_probe_spec(f"png:{work / 'masks' / 'sem'}")
    stru = parse_probe_spec(f"sam-json:{work / 'masks' / 'str'}")
    t = time.perf_counter()
    res = evaluate(bundle, out=work / "out", semantic_probes=[sem], structural_probes=[stru],
                   options=EvaluateOptions(pictures=not args.no_pictures), device=ctx, progress=True)
    total = time.perf_counter() - t
    from r360gpu.report.outputs import write_outputs

    t = time.perf_counter()
    write_outputs(res, work / "out")
    t_report = time.perf_counter() - t
    stages = res["timing"]["stages_s"]
    n = len(res["scenes"]["room"]["views"])
    print(f"\ngenerated the scene in {t_gen:.1f} s; wrote precomputed masks in {t_masks:.1f} s (not timed below)")
    print(f"{'stage':<14}{'seconds':>10}{'per view (ms)':>16}")
    for k, v in stages.items():
        print(f"{k:<14}{v:>10.1f}{v / n * 1e3:>16.1f}")
    print(f"{'report':<14}{t_report:>10.1f}{t_report / n * 1e3:>16.1f}")
    print(f"{'total':<14}{total + t_report:>10.1f}{(total + t_report) / n * 1e3:>16.1f}")
    print(f"views/s: {n / (total + t_report):.2f} ({n} views x (pre + reference + {len(methods)} methods) renders)")
    ax = res["aggregate"]["overall"]
    print("overall: " + ", ".join(f"{m}: RQS {a['rqs']:.3f}" for m, a in ax.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
