"""How far the axes of a framed scene can agree with the unframed one: float32 storage against the 1e-6 target.

    ./r360 python bench/frame_precision.py [--keep DIR]

The synthetic room of ``tests/test_frame_invariance.py`` (clean and floaters, 5 views at 160x120) is
scored as generated, then per draw of that test (scale 0.1, 0.388, 10; the same seeded similarities)
three ways, each printed as the largest differences of its axes entries against the unframed run:

* **framed**: every splat file moved by the similarity and stored (float32 PLY), the frame declared:
  what r360gpu scores (the cameras are moved into the frame);
* **undone in float64**: the same float32 files, moved back into the cameras' world in float64
  (centres, scales, rotations) and stored again, no frame declared: the best any handling of the
  declared frame could do from those files;
* and, per seed, **no frame, centres moved by <= 1 ulp**: the unframed files with every centre
  coordinate moved to a random float32 neighbour (or kept): no frame at all, the rounding a float32
  file carries whatever wrote it.

If the third row is not within 1e-6, no handling of a declared frame can be: the float32 coordinates
of a moved file differ from the unframed ones by at least that much, in the cameras' world by about
``ulp(|x'|) / s`` (``x'`` the moved centre, ``s`` the frame's scale).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # shared with the frame tests
from frame_outputs import ARGS, rewritten, ulp_moved, undone  # noqa: E402

DRAWS = ((0.1, 0.1), (0.1, 10.0), (10.0, 10.0))  # as tests/test_frame_invariance.py, seeds 100 + draw


def largest(a: dict, b: dict, n: int = 3) -> str:
    """The ``n`` largest |a - b| over the numbers of two {method: axes} trees, worded."""
    diffs = sorted(((abs(v - b[m][k]), f"{m}.{k}") for m in a for k, v in a[m].items()
                    if isinstance(v, float) and isinstance(b[m].get(k), float)), reverse=True)
    return ", ".join(f"{k} {d:.2g}" for d, k in diffs[:n]) if diffs and diffs[0][0] > 0 else "every number identical"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--keep", type=Path, help="work in this folder (kept) instead of a temporary one")
    args = p.parse_args()
    from r360gpu.bundle import load_bundle
    from r360gpu.gpu import get_context
    from r360gpu.io import load_gaussians
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.synthetic import generate_benchmark
    from r360gpu.synthetic.frames import moved_bundle, random_similarity

    ctx = get_context()
    opts = EvaluateOptions(n_boot=50, n_perm=20, pictures=False, boundary=False, controls=False)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        room = generate_benchmark(root / "gen", scenes=("room",), methods=("clean", "floaters"), ctx=ctx, **ARGS)[0]

        def axes(folder: Path) -> dict:
            res = evaluate(load_bundle(folder), out=root / "out" / folder.name, device=ctx, progress=False, options=opts)
            return {m: e["axes"] for m, e in res["scenes"]["room"]["methods"].items()}

        plain = axes(room)
        print("unframed: " + "; ".join(f"{m} s_str {a['s_str']:.4f}" for m, a in plain.items()))
        for draw, scale in enumerate(DRAWS):
            frame = random_similarity(np.random.default_rng(100 + draw), scale=scale)
            moved = moved_bundle(room, root / f"framed{draw}", frame)
            print(f"scale {frame.scale:.3g}, framed:            {largest(axes(moved), plain)}", flush=True)
            back = rewritten(room, root / f"undone{draw}", lambda rel: undone(load_gaussians(moved / rel), frame))
            print(f"scale {frame.scale:.3g}, undone in float64: {largest(axes(back), plain)}", flush=True)
        for seed in range(3):
            nudged = rewritten(room, root / f"ulp{seed}",
                               lambda rel: ulp_moved(load_gaussians(room / rel), np.random.default_rng(seed)))
            print(f"no frame, centres moved by <= 1 ulp (seed {seed}): {largest(axes(nudged), plain)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
