"""Write tests/data/compat_public/office_chair: a small public-layout folder with adversarial views.

Deterministic (seeded); re-running it rewrites the same files.  The expected
numbers come from running the public modules on it
(bench/public_peer/run_public_eval.py), never from r360gpu.

Views (128x96):
  v00  8-bit grey depth; object removed (depth jumps back); post-only holes (post 0) and
       pre-only holes (pre 0) inside the target; GSAM2 finds the object before, a residual after
  v01  16-bit depth (PIL convert("L") clips at 255); GSAM2 after missing (empty prediction)
  v02  RGB depth (luma); GSAM2 before at half size (resized to the largest); GSAM2 after an RGB
       mask whose (0,0,1) pixels are 0 in IMREAD_GRAYSCALE; SAM masks at 1/8 size
  v03  empty target; GSAM2 after still fires (IoU 0: "not detected"); depth acc 0
  v04  identical depth before/after (|dD| = 0 everywhere: a constant mask written all white)
  v05  palette depth with a constant |dD| = 20; target drawn with value 100 (cv2 > 0 keeps it,
       PIL > 128 drops it for the SAM evaluation)
  v06  depth pair and renderings but no target mask (the depth script scores it 0)
SAM: masks/VIEW.json (GT) for v00..v05, sam/after/VIEW.json for v00..v04 (segmentations 16x12).
"""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

W, H = 128, 96
ROOT = Path(__file__).resolve().parents[2] / "tests" / "data" / "compat_public" / "office_chair"


def box(y0, y1, x0, x1, shape=(H, W)):
    m = np.zeros(shape, np.uint8)
    m[y0:y1, x0:x1] = 1
    return m


def write_png(path: Path, arr, mode=None):
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(arr, mode) if mode else Image.fromarray(arr)
    (Image.fromarray(arr) if mode is None else Image.fromarray(arr).convert(mode)).save(path, optimize=True)


def scene_depth(rng, near):
    yy, xx = np.mgrid[0:H, 0:W]
    back = 140 + 40 * yy / H
    d = back.copy()
    obj = box(30, 70, 40, 90).astype(bool)
    if near:
        d[obj] = 10 + 30 * xx[obj] / W + 8 * (yy[obj] % 7 == 0)
    return np.clip(d, 0, 255).astype(np.uint8), obj


def sam_records(masks_small):
    return [{"segmentation": m.astype(int).tolist(), "area": int(m.sum())} for m in masks_small]


def main() -> int:
    if ROOT.exists():
        shutil.rmtree(ROOT)
    rng = np.random.default_rng(360)
    target = box(30, 70, 40, 90)
    views = [f"v0{i}" for i in range(7)]
    for i, v in enumerate(views):
        rgb_pre = np.full((H, W, 3), (90, 110, 130), np.uint8)
        rgb_pre[30:70, 40:90] = (200, 60, 40)
        rgb_post = np.full((H, W, 3), (90, 110, 130), np.uint8)
        write_png(ROOT / "rgb" / "before" / f"{v}.png", rgb_pre)
        write_png(ROOT / "rgb" / "after" / f"{v}.png", rgb_post)
    # depth
    pre0, obj = scene_depth(rng, True)
    post0, _ = scene_depth(rng, False)
    pre0[35:45, 50:60] = 200         # a far patch seen through the object before removal ...
    post0[35:45, 50:60] = 0          # ... with no post depth: the scripts keep |dD| = D_pre = 200 there
    pre0[55:60, 70:85] = 0           # pre-only holes: zeroed
    write_png(ROOT / "depth" / "before" / "v00.png", pre0)
    write_png(ROOT / "depth" / "after" / "v00.png", post0)
    pre1 = (pre0.astype(np.uint16) * 2)   # 16-bit: values 140..400, clipped at 255 by convert("L")
    post1 = (post0.astype(np.uint16) * 2)
    for name, a in (("before", pre1), ("after", post1)):
        p = ROOT / "depth" / name / "v01.png"
        assert cv2.imwrite(str(p), a)
    pre2 = np.stack([pre0, (pre0 // 2), 255 - pre0], -1).astype(np.uint8)
    post2 = np.stack([post0, (post0 // 2), 255 - post0], -1).astype(np.uint8)
    write_png(ROOT / "depth" / "before" / "v02.png", pre2)
    write_png(ROOT / "depth" / "after" / "v02.png", post2)
    write_png(ROOT / "depth" / "before" / "v03.png", pre0)
    write_png(ROOT / "depth" / "after" / "v03.png", post0)
    write_png(ROOT / "depth" / "before" / "v04.png", pre0)
    write_png(ROOT / "depth" / "after" / "v04.png", pre0)
    pre5 = np.full((H, W), 100, np.uint8)
    post5 = np.full((H, W), 120, np.uint8)
    Image.fromarray(pre5).convert("P").save(ROOT / "depth" / "before" / "v05.png")
    Image.fromarray(post5).convert("P").save(ROOT / "depth" / "after" / "v05.png")
    write_png(ROOT / "depth" / "before" / "v06.png", pre0)
    write_png(ROOT / "depth" / "after" / "v06.png", post0)
    # target masks (v06 has none)
    for v in views[:6]:
        m = np.zeros((H, W), np.uint8) if v == "v03" else target * 255
        if v == "v05":
            m = target * 100
        write_png(ROOT / "masks" / f"{v}.png", m.astype(np.uint8))
    # GSAM2 PNG masks
    g = ROOT / "gsam2"
    write_png(g / "before" / "mask" / "v00.png", box(32, 70, 42, 92) * 255)
    write_png(g / "after" / "mask" / "v00.png", box(40, 50, 60, 75) * 255)
    write_png(g / "before" / "mask" / "v01.png", box(30, 66, 40, 88) * 255)
    half = box(15, 35, 20, 45, (H // 2, W // 2)) * 255
    write_png(g / "before" / "mask" / "v02.png", half.astype(np.uint8))
    rgb_after = np.zeros((H, W, 3), np.uint8)
    rgb_after[30:70, 40:90] = (0, 0, 1)          # IMREAD_GRAYSCALE: 0
    rgb_after[30:40, 40:60] = (255, 255, 255)
    write_png(g / "after" / "mask" / "v02.png", rgb_after)
    write_png(g / "before" / "mask" / "v03.png", box(10, 20, 10, 20) * 255)
    write_png(g / "after" / "mask" / "v03.png", box(10, 20, 10, 20) * 255)
    write_png(g / "before" / "mask" / "v04.png", target * 255)
    write_png(g / "after" / "mask" / "v04.png", target * 255)
    write_png(g / "before" / "mask" / "v05.png", box(30, 70, 40, 80) * 255)
    write_png(g / "after" / "mask" / "v05.png", box(30, 70, 40, 60) * 255)
    # SAM JSON at 16x12 (resized by the scripts with cv2.INTER_NEAREST)
    sw, sh = 16, 12
    s = lambda y0, y1, x0, x1: box(y0, y1, x0, x1, (sh, sw))  # noqa: E731
    obj_s, part_s, bg_s, left_s = s(4, 9, 5, 11), s(4, 6, 5, 8), s(0, 2, 0, 16), s(4, 9, 5, 8)
    gt = {"v00": [obj_s, bg_s, part_s], "v01": [obj_s, bg_s], "v02": [obj_s, left_s],
          "v03": [obj_s, bg_s], "v04": [obj_s], "v05": [obj_s, part_s]}
    post = {"v00": [s(4, 7, 5, 9), bg_s], "v01": [bg_s], "v02": [left_s, obj_s, part_s], "v03": [obj_s], "v04": [obj_s]}
    for v, ms in gt.items():
        (ROOT / "masks" / f"{v}.json").write_text(json.dumps(sam_records(ms), separators=(",", ":")))
    (ROOT / "sam" / "after").mkdir(parents=True)
    for v, ms in post.items():
        (ROOT / "sam" / "after" / f"{v}.json").write_text(json.dumps(sam_records(ms), separators=(",", ":")))
    (ROOT / "prompt.txt").write_text("chair\n")
    print(f"wrote {ROOT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
