"""``r360gpu inpaint 360usid`` against AuraFusion360's evaluation definitions run in plain numpy, on one
generated 360-USID-shaped folder, in one process.

The folder (``r360gpu.synthetic.inpaint_folders``: JPEG photographs, two methods' PNG renders,
anti-aliased object masks) has ``--scenes`` scenes x ``--views`` views at ``--width`` x ``--height``
(7 x 30 at 1008 x 567 by default: 360-USID's seven scenes).  Timed, each once, every scene and both methods:

* ours: ``r360gpu.cli.main(["inpaint", "360usid", ...])`` in default mode and in ``--compat``
  (reading, scoring, writing results.json / csv / tables / report.html);
* the script's definitions: tests/aura_eval_oracle.py (a float32 numpy model of aura_eval.py's
  PSNR, SSIM, masked PSNR and masked SSIM, its SSIM correlation done as two 1-D passes with
  scipy.ndimage, as a numpy port would; LPIPS and FID are not in either side).

Printed: both wall times, their ratio, and the largest difference between our compat per-scene means
and the numpy model's (they must agree to 1e-4).

    ./r360 python bench/inpaint_vs_script.py [--scenes 7] [--views 30] [--width 1008] [--height 567]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from r360gpu.cli import main  # noqa: E402
from r360gpu.metrics.json_values import dec_tree  # noqa: E402
from r360gpu.synthetic.inpaint_folders import METHODS, SCENES, write_inpaint_example  # noqa: E402
from tests import aura_eval_oracle as oracle  # noqa: E402


def _ours(usid: Path, out: Path, *extra: str) -> float:
    args = ["inpaint", "360usid", str(usid / "data"),
            *(f"{m}={usid}/output/{{scene}}/test/{m}" for m in METHODS),
            "--masks", f"{usid}/output/{{scene}}/test/ours_30000/object_mask", "--out", str(out), "--quiet", *extra]
    t = time.perf_counter()
    if main(args) != 0:
        raise SystemExit("r360gpu inpaint failed")
    return time.perf_counter() - t


def main_(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", type=int, default=7)
    p.add_argument("--views", type=int, default=30)
    p.add_argument("--width", type=int, default=1008)
    p.add_argument("--height", type=int, default=567)
    a = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="r360-inpaint-bench-") as tmp:
        tmp = Path(tmp)
        t = time.perf_counter()
        usid = write_inpaint_example(tmp / "ex", n_scenes=a.scenes, n_views=a.views, width=a.width,
                                     height=a.height)["360usid"]
        print(f"folder: {a.scenes} scenes x {a.views} views x {len(METHODS)} methods at {a.width}x{a.height} "
              f"written in {time.perf_counter() - t:.1f} s")
        t_default = _ours(usid, tmp / "default")
        t_compat = _ours(usid, tmp / "compat", "--compat")
        t = time.perf_counter()
        ref = {(s, m): oracle.score_usid_scene(usid / "data" / s, usid / "output" / s / "test" / m,
                                               usid / "output" / s / "test" / "ours_30000" / "object_mask",
                                               separable=True)
               for s in SCENES[:a.scenes] for m in METHODS}
        t_numpy = time.perf_counter() - t
        doc = dec_tree(json.loads((tmp / "compat" / "results.json").read_text()))
        worst = max(abs(doc["scenes"][s][m]["means"][k]["mean"] - v)
                    for (s, m), means in ref.items() for k, v in means.items() if math.isfinite(v))
    print(f"r360gpu inpaint (default mode): {t_default:.1f} s")
    print(f"r360gpu inpaint --compat:       {t_compat:.1f} s")
    print(f"script definitions in numpy:    {t_numpy:.1f} s")
    print(f"ratio numpy / r360gpu: {t_numpy / t_default:.2f}x (default), {t_numpy / t_compat:.2f}x (compat)")
    print(f"largest |compat mean - numpy mean| over scenes, methods, metrics: {worst:.2e}")
    return 0 if worst <= 1e-4 else 1


if __name__ == "__main__":
    sys.exit(main_())
