"""Reading SAM JSON mask files as the public scripts write them (``json.dump`` of
``{"segmentation": bool_mask.tolist(), "area", "bbox"}`` records): the fast
reader (r360gpu.probes.sam_json) vs the standard way it replaced (json.loads +
np.array of the nested lists, as read_sam_records does on plain lists), and vs
the same reader with its true/false fast path (parse_bool_grid) turned off.

    python bench/bench_sam_json.py [--views 5] [--masks 4] [--width 1200] [--height 1000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import blob_masks  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--views", type=int, default=5)
    ap.add_argument("--masks", type=int, default=4)
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from r360gpu.probes.precomputed import read_sam_json, read_sam_records

    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for v in range(args.views):
            masks = blob_masks(args.masks, args.height, args.width, rng).astype(bool)
            recs = [{"segmentation": m.tolist(), "area": int(m.sum()), "bbox": [0, 0, 1, 1]} for m in masks]
            p = Path(tmp) / f"{v:05d}.json"
            with open(p, "w") as f:
                json.dump(recs, f)
            paths.append(p)
        mb = sum(p.stat().st_size for p in paths) / 1e6

        def standard():
            return [read_sam_records(json.loads(p.read_bytes().decode("utf-8")), p) for p in paths]

        def fast():
            return [read_sam_json(p) for p in paths]

        def generic():  # the reader with its true/false fast path off: every grid through parse_grid
            from r360gpu.probes import sam_json

            keep = sam_json.parse_bool_grid
            sam_json.parse_bool_grid = lambda *a: None
            try:
                return fast()
            finally:
                sam_json.parse_bool_grid = keep

        best = {"standard": np.inf, "generic": np.inf, "fast": np.inf}
        for _ in range(args.repeat):
            for name, fn in (("standard", standard), ("generic", generic), ("fast", fast)):
                t = time.perf_counter()
                out = fn()
                best[name] = min(best[name], time.perf_counter() - t)
                if name == "standard":
                    ref = out
                else:
                    for a, b in zip(out, ref):
                        assert np.array_equal(a.masks, b.masks)
    print(f"# SAM JSON reading: {args.views} files x {args.masks} masks of {args.height}x{args.width} "
          f"({mb:.0f} MB); best of {args.repeat}, CPU cores: {os.cpu_count()}")
    print(f"{'reader':<46}{'time (s)':>10}{'per mask (ms)':>16}{'speed-up':>10}")
    n = args.views * args.masks
    for name, label in (("standard", "standard (json.loads + np.array of lists)"),
                        ("generic", "sam_json, generic path only (parse_grid)"), ("fast", "r360gpu.probes.sam_json")):
        print(f"{label:<46}{best[name]:>10.2f}{best[name] / n * 1e3:>16.1f}{best['standard'] / best[name]:>9.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
