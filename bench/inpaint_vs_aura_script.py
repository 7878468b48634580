"""``r360gpu inpaint 360usid --compat`` against AuraFusion360's own metric code, run in torch.

The peer is the public script's arithmetic itself: ``utils/image_utils.py`` (``psnr``,
``masked_psnr``) and ``utils/loss_utils.py`` (``ssim``) imported from a checkout of
superlearnerG/my-AuraFusion360, driven by the loop of ``scripts/aura_eval.py`` (PIL ``convert("RGB")``,
torchvision ``to_tensor``, the mask read as it is with ``mask[mask > 0.5] = 1``, masked SSIM of both
images times the mask, ``np.mean`` over the views), on the CPU instead of CUDA.  LPIPS and FID are
left to bench/inpaint_models_vs_peers.py (they need the network exports).

Runs in a throwaway environment with torch, torchvision, natsort and matplotlib (the script's
imports), never in CI; r360gpu runs through ``--r360`` (the checkout's ``./r360``) in its own
environment, in the same run::

    VENV/bin/python bench/inpaint_vs_aura_script.py --aura AURA_CHECKOUT --work /tmp/aura-bench

Prints, per scene, method and metric, the script's mean, r360gpu's and the difference; the largest
difference; and both wall times.
"""
from __future__ import annotations

import argparse
import glob
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
METRICS = ("psnr", "ssim", "masked_psnr", "masked_ssim")


def script_means(aura: Path, usid: Path, scene: str, method: str) -> dict[str, float]:
    """The per-scene means as aura_eval.py computes them (its loop, on the CPU)."""
    sys.path.insert(0, str(aura))
    import numpy as np
    import torch
    import torchvision.transforms.functional as tf
    from natsort import natsorted
    from PIL import Image
    from utils.image_utils import masked_psnr, psnr
    from utils.loss_utils import ssim

    gt_imgs = natsorted(glob.glob(f"{usid}/data/{scene}/test_images/*jpg"))
    object_masks = natsorted(glob.glob(f"{usid}/output/{scene}/test/ours_30000/object_mask/*.png"))
    method_imgs = natsorted(glob.glob(f"{usid}/output/{scene}/test/{method}/renders/*png"))
    assert len(gt_imgs) == len(object_masks) == len(method_imgs) > 0, (scene, method)
    vals = {k: [] for k in METRICS}
    with torch.no_grad():
        for i in range(len(gt_imgs)):
            gt = tf.to_tensor(Image.open(gt_imgs[i]).convert("RGB")).unsqueeze(0)[:, :3, :, :]
            mask = tf.to_tensor(Image.open(object_masks[i])).unsqueeze(0)[:, :3, :, :]
            mask[mask > 0.5] = 1
            img = tf.to_tensor(Image.open(method_imgs[i]).convert("RGB")).unsqueeze(0)[:, :3, :, :]
            vals["masked_psnr"].append(float(masked_psnr(img, gt, mask)))
            vals["masked_ssim"].append(ssim(img * mask.repeat(1, 3, 1, 1), gt * mask.repeat(1, 3, 1, 1)).item())
            vals["ssim"].append(ssim(img, gt).item())
            vals["psnr"].append(psnr(img, gt).item())
    return {k: float(np.mean(v)) for k, v in vals.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--aura", required=True, type=Path, help="checkout of superlearnerG/my-AuraFusion360")
    ap.add_argument("--work", required=True, type=Path, help="scratch folder (the example and r360gpu's output)")
    ap.add_argument("--r360", default=str(ROOT / "r360"), help="r360gpu's command (default: this checkout's ./r360)")
    ap.add_argument("--n-scenes", type=int, default=3)
    ap.add_argument("--n-views", type=int, default=8)
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--height", type=int, default=135)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    for f in ("utils/image_utils.py", "utils/loss_utils.py"):
        if not (a.aura / f).is_file():
            ap.error(f"{a.aura / f} not found: --aura must be a checkout of superlearnerG/my-AuraFusion360")
    ex, out = a.work / "example", a.work / "r360gpu"
    subprocess.run([a.r360, "inpaint", "example", str(ex), "--n-scenes", str(a.n_scenes), "--n-views",
                    str(a.n_views), "--width", str(a.width), "--height", str(a.height), "--seed", str(a.seed)],
                   check=True, cwd=ROOT)
    usid = ex / "360usid"
    scenes = sorted(p.name for p in (usid / "data").iterdir() if p.is_dir())
    methods = sorted(p.name for p in (usid / "output" / scenes[0] / "test").iterdir()
                     if (p / "renders").is_dir())
    t0 = time.perf_counter()
    subprocess.run([a.r360, "inpaint", "360usid", str(usid / "data"),
                    *(f"{m}={usid}/output/{{scene}}/test/{m}" for m in methods),
                    "--masks", f"{usid}/output/{{scene}}/test/ours_30000/object_mask", "--compat", "--quiet",
                    "--out", str(out)], check=True, cwd=ROOT, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    t_ours = time.perf_counter() - t0
    doc = json.loads((out / "results.json").read_text())
    t0 = time.perf_counter()
    theirs = {(s, m): script_means(a.aura, usid, s, m) for s in scenes for m in methods}
    t_script = time.perf_counter() - t0
    worst = 0.0
    print(f"{'scene':<12} {'method':<8} {'metric':<12} {'script':>12} {'r360gpu':>12} {'|diff|':>10}")
    for (s, m), vals in theirs.items():
        for k in METRICS:
            ours = doc["scenes"][s][m]["means"][k]["mean"]
            if isinstance(ours, dict):  # NaN / inf as the results document writes them
                ours = float(ours["__float__"])
            d = abs(ours - vals[k]) if math.isfinite(vals[k]) else (0.0 if ours == vals[k] else math.inf)
            worst = max(worst, d)
            print(f"{s:<12} {m:<8} {k:<12} {vals[k]:12.6f} {ours:12.6f} {d:10.2e}")
    n = len(scenes) * a.n_views
    print(f"\n{len(scenes)} scenes x {a.n_views} views at {a.width}x{a.height}, {len(methods)} methods: "
          f"largest difference {worst:.2e} (target 1e-4)")
    print(f"wall: r360gpu inpaint --compat {t_ours:.2f} s (whole process, {n} views); "
          f"the script's metric code in torch on the CPU {t_script:.2f} s; ratio {t_script / t_ours:.2f}")
    return 0 if worst <= 1e-4 else 1


if __name__ == "__main__":
    sys.exit(main())
