"""Demonstration of the weight-free built-in probes on a synthetic scene.

A synthetic room (wall, picture frame, wooden floor) with a textured blue
"sofa" is rendered from five poses (the sofa shifts across the frame and the
lighting changes a little).  The appearance probe is fitted on the pre
renderings of four poses and evaluated on the fifth, held-out pose, whose
post-removal rendering is one of:

* ``clean``      -- the background, as a perfect removal (also the reference I_ref);
* ``flat-fill``  -- the sofa's pixels replaced by one flat colour (mean of
  the surrounding background), as a weak inpainter does;
* ``residual``   -- the left half of the sofa left in place;
* ``blurred``    -- the whole sofa left in place but smeared (Gaussian blur);
* ``faded``      -- the sofa half transparent over the background (50% blend);
* ``floaters``   -- six small blobs of sofa texture scattered over the removed region;
* ``recoloured`` -- the sofa's shape left in place but painted a darker
  shade of the floor (shape-only evidence).

Printed per case: the appearance probe's IoU with the target mask M
(acc_seg counts a view as removed when IoU_post < 0.3); for each structural
probe the number of masks, the best IoU of one mask with M, the number of
masks retained (IoU with M >= 0.1) and sim_SAM against the clean reference
(Hungarian matching of the retained sets, docs/protocol.md); and timings.

Run: /work/venv/bin/python bench/demo_builtin_probes.py [--size 1920x1080] [--threads 1]
"""
from __future__ import annotations

import argparse
import time

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from r360gpu.probes.builtin_semantic import BuiltinAppearanceProbe
from r360gpu.probes.builtin_structural import BuiltinStructuralProbe, StructuralParams

POSES = (0.30, 0.40, 0.50, 0.60, 0.70)  # sofa centre, fraction of the width
GAINS = (0.94, 1.03, 1.00, 0.97, 1.06)  # per-pose lighting
HELD_OUT = 2
CASES = ("clean", "flat-fill", "residual", "blurred", "faded", "floaters", "recoloured")


def _smooth_noise(rng: np.random.Generator, h: int, w: int, sigma_px: float, amplitude: float) -> np.ndarray:
    noise = rng.standard_normal((h, w)).astype(np.float32)
    if sigma_px > 0.3:
        noise = cv2.GaussianBlur(noise, (0, 0), sigma_px)
        noise /= max(float(noise.std()), 1e-6)
    return noise * np.float32(amplitude)


def background(h: int, w: int, pose: int) -> np.ndarray:
    """float32 (h, w, 3) RGB 0..255 of the empty room at one pose."""
    rng = np.random.default_rng(pose)
    y = np.arange(h, dtype=np.float32)[:, None] / h
    x = np.arange(w, dtype=np.float32)[None, :] / w
    img = np.zeros((h, w, 3), np.float32)
    horizon = 0.50
    wall = y < horizon
    shade = 12.0 * (0.5 - y) + _smooth_noise(rng, h, w, 0.01 * w, 2.0)
    for c, v in enumerate((205.0, 195.0, 175.0)):
        img[..., c] = np.where(wall, v + shade, 0.0)
    stripes = 6.0 * np.sin(2 * np.pi * y / 0.025) + _smooth_noise(rng, h, w, 0.002 * w, 3.0)
    for c, v in enumerate((125.0, 90.0, 62.0)):
        img[..., c] = np.where(wall, img[..., c], v + stripes * (1.0 - 0.3 * c))
    frame = (np.abs(x - 0.8 + 0.1 * (pose - HELD_OUT) / 4) < 0.07) & (np.abs(y - 0.22) < 0.09)
    inner = (np.abs(x - 0.8 + 0.1 * (pose - HELD_OUT) / 4) < 0.055) & (np.abs(y - 0.22) < 0.07)
    img[frame & ~inner] = (40.0, 80.0, 50.0)
    img[inner] = (225.0, 215.0, 190.0)
    return img


def sofa(h: int, w: int, pose: int) -> tuple[np.ndarray, np.ndarray]:
    """(bool (h, w) mask M, float32 (h, w, 3) sofa colours) at one pose."""
    rng = np.random.default_rng(100 + pose)
    cx = POSES[pose]
    y = (np.arange(h, dtype=np.float32)[:, None] + 0.5) / h
    x = (np.arange(w, dtype=np.float32)[None, :] + 0.5) / w
    seat = (np.abs(x - cx) < 0.10) & (y > 0.50) & (y < 0.66)
    back = ((x - cx) / 0.09) ** 2 + ((y - 0.50) / 0.08) ** 2 < 1.0
    mask = seat | back
    fabric = _smooth_noise(rng, h, w, 0.0012 * w, 12.0)
    seams = np.where((np.abs(x - cx) % 0.07) < 0.004, -25.0, 0.0).astype(np.float32)
    shade = 20.0 * (0.6 - y)
    colours = np.zeros((h, w, 3), np.float32)
    for c, v in enumerate((50.0, 75.0, 150.0)):
        colours[..., c] = v + fabric + seams + shade
    return mask, colours


def render(h: int, w: int, pose: int, case: str) -> tuple[np.ndarray, np.ndarray]:
    """(uint8 (h, w, 3) RGB, bool (h, w) M) of one pose: ``case`` is "pre" or one of CASES."""
    bg = background(h, w, pose)
    mask, colours = sofa(h, w, pose)
    img = bg.copy()
    if case == "pre":
        img[mask] = colours[mask]
    elif case == "flat-fill":
        ring = cv2.dilate(mask.astype(np.uint8), np.ones((15, 15), np.uint8)).astype(bool) & ~mask
        img[mask] = bg[ring].mean(axis=0)
    elif case == "residual":
        left = mask & (np.arange(w)[None, :] < POSES[pose] * w)
        img[left] = colours[left]
    elif case == "blurred":
        with_sofa = bg.copy()
        with_sofa[mask] = colours[mask]
        smeared = cv2.GaussianBlur(with_sofa, (0, 0), 0.006 * w)
        img[mask] = smeared[mask]
    elif case == "faded":
        img[mask] = 0.5 * bg[mask] + 0.5 * colours[mask]
    elif case == "floaters":
        rng = np.random.default_rng(7)
        ys, xs = np.nonzero(mask)
        blobs = np.zeros((h, w), np.uint8)
        for i in rng.choice(ys.size, 6, replace=False):
            cv2.circle(blobs, (int(xs[i]), int(ys[i])), max(1, int(0.02 * w)), 1, -1)
        blobs = blobs.astype(bool)
        img[blobs] = colours[blobs]
    elif case == "recoloured":
        img[mask] = bg[mask] * 0.8
    elif case != "clean":
        raise ValueError(case)
    img *= GAINS[pose]
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), mask


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 0.0


def retained(masks: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Masks with IoU >= 0.1 with the target (docs/protocol.md, structural axis)."""
    keep = [i for i, m in enumerate(masks) if iou(m, target) >= 0.1]
    return masks[keep]


def sim_sam(a: np.ndarray, b: np.ndarray) -> float:
    """sim^v between two retained mask sets (docs/protocol.md)."""
    if len(a) == 0 and len(b) == 0:
        return 1.0
    if len(a) == 0 or len(b) == 0:
        return 0.0
    matrix = np.array([[iou(p, q) for q in b] for p in a])
    rows, cols = linear_sum_assignment(matrix, maximize=True)
    return float(matrix[rows, cols].sum() / max(len(a), len(b)))


def _timed(fn, repeats: int):
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return out, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="1920x1080", help="WxH of the renderings")
    parser.add_argument("--threads", type=int, default=1, help="OpenCV threads (timings are for this many)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (best is reported)")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.lower().split("x"))
    cv2.setNumThreads(args.threads)

    fit_poses = [p for p in range(len(POSES)) if p != HELD_OUT]
    pre = [render(h, w, p, "pre") for p in fit_poses]
    probe = BuiltinAppearanceProbe()
    _, fit_s = _timed(lambda: probe.fit([im for im, _ in pre], [m for _, m in pre]), args.repeats)
    structural = [BuiltinStructuralProbe(), BuiltinStructuralProbe(StructuralParams.slic())]

    pre_img, target = render(h, w, HELD_OUT, "pre")
    images = {"pre (held out)": pre_img}
    images.update({case: render(h, w, HELD_OUT, case)[0] for case in CASES})
    ref_sets = {s.name: retained(s.predict_image(images["clean"]).masks, target) for s in structural}

    print(f"renderings {w}x{h}, target M covers {target.mean():.1%} of the image; OpenCV threads: {args.threads}")
    print(f"appearance fit on {len(pre)} pre renderings of other poses: {fit_s:.3f} s")
    header = f"{'case':16s} | {'appear. IoU':>11s} {'inst.':>5s} |"
    for s in structural:
        header += f" {s.name + ': masks':>23s} {'best IoU':>8s} {'kept':>4s} {'sim vs clean':>12s} |"
    print(header)
    times = {probe.name: [], **{s.name: [] for s in structural}}
    for case, img in images.items():
        pred, dt = _timed(lambda: probe.predict_image(img, "sofa"), args.repeats)
        times[probe.name].append(dt)
        row = f"{case:16s} | {iou(pred.union(), target):11.3f} {pred.count:5d} |"
        for s in structural:
            ms, dt = _timed(lambda: s.predict_image(img), args.repeats)
            times[s.name].append(dt)
            best = max((iou(m, target) for m in ms.masks), default=0.0)
            kept = retained(ms.masks, target)
            row += f" {ms.count:23d} {best:8.3f} {len(kept):4d} {sim_sam(kept, ref_sets[s.name]):12.3f} |"
        print(row)
    for name, values in times.items():
        print(f"{name}: {np.median(values):.3f} s per {w}x{h} image (median over cases, best of {args.repeats})")
    photo_counts(structural)


def photo_counts(structural) -> None:
    """Masks per image on a real photograph (matplotlib's sample portrait), when matplotlib is installed."""
    try:
        from matplotlib import cbook
    except ImportError:
        print("matplotlib not installed: no photograph counts")
        return
    bgr = cv2.imread(cbook.get_sample_data("grace_hopper.jpg", asfileobj=False))
    photo = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    sizes = [(photo.shape[1], photo.shape[0]), (1920, 1080), (320, 180), (160, 90)]
    for s in structural:
        counts = []
        for sw, sh in sizes:
            img = photo if (sw, sh) == sizes[0] else cv2.resize(photo, (sw, sh), interpolation=cv2.INTER_AREA)
            counts.append(f"{sw}x{sh}: {s.predict_image(img).count}")
        print(f"{s.name} masks on matplotlib's grace_hopper.jpg, resized to: " + ", ".join(counts))


if __name__ == "__main__":
    main()
