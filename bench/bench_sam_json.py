"""Reading SAM JSON mask files as the public scripts write them (``json.dump`` of
``{"segmentation": bool_mask.tolist(), "area", "bbox"}`` records): the fast
reader (r360gpu.probes.sam_json) vs the standard way it replaced (json.loads +
np.array of the nested lists, as read_sam_records does on plain lists), and vs
the same reader with its true/false fast path (parse_bool_grid) turned off.
Then the two ways of that fast path on single masks with more and more runs
of ``true`` (parse_bool_runs, parse_bool_tokens), where the dispatcher's
threshold (one run per ``_BYTES_PER_RUN`` bytes) sits among them.

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

    from r360gpu.probes.sam_records import read_sam_json, read_sam_records

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
    runs_table(args.height, args.width, args.repeat)
    return 0


def runs_table(h: int, w: int, repeat: int) -> None:
    """Per-mask time of the run and token ways as the runs of ``true`` per row grow."""
    from r360gpu.probes import sam_json

    print(f"\n# true/false grid, {h}x{w}, by runs of true per row (best of {repeat})")
    print(f"{'runs/row':>9}{'bytes/run':>11}{'runs (ms)':>11}{'tokens (ms)':>13}{'dispatcher takes':>18}")
    for per_row in (1, 4, 8, 16, 64, 256):
        period = max(2, w // per_row)
        grid = (np.arange(w)[None, :] % period < period // 2) & (np.arange(h)[:, None] >= 0)
        raw = json.dumps(grid.tolist()).encode()
        n_runs = int(grid[:, 0].sum() + (grid[:, 1:] & ~grid[:, :-1]).sum())
        best = {}
        for name, fn in (("runs", sam_json.parse_bool_runs), ("tokens", sam_json.parse_bool_tokens)):
            ts = []
            for _ in range(repeat):
                t = time.perf_counter()
                got = fn(raw, 0, len(raw))
                ts.append(time.perf_counter() - t)
                assert np.array_equal(got, grid)
            best[name] = min(ts)
        takes = "runs" if n_runs <= max(16, len(raw) // sam_json._BYTES_PER_RUN) else "tokens"
        print(f"{per_row:>9}{len(raw) // max(1, n_runs):>11}{best['runs'] * 1e3:>11.1f}{best['tokens'] * 1e3:>13.1f}"
              f"{takes:>18}")


if __name__ == "__main__":
    sys.exit(main())
