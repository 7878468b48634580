"""Encoding one contact sheet as PNG: r360gpu's encoder (report.png: "up" row filter,
ISA-L deflate) against OpenCV's libpng at level 6 and level 1 (adaptive filters, and the
"up" filter it used before), and against its own format with the standard zlib, in one run.

The sheet is built by report.contact_sheets.sheet_image from rendered-looking panels
(smooth gradients, noise, a flat-coloured object, mask outlines), 8 panels at
the default panel width, as `r360gpu score` writes one per method and view.
Every encoding is decoded again and checked equal to the sheet (lossless).

    python bench/bench_png.py [--repeat 10]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import cv2
import numpy as np


def make_sheet(rng) -> np.ndarray:
    from r360gpu.report.contact_sheets import sheet_image

    h, w = 360, 480
    yy, xx = np.mgrid[:h, :w].astype(np.float32)
    panels = []
    for k in range(8):
        img = np.stack([xx / w, yy / h, 0.5 + 0.5 * np.sin(xx / (17 + k) + yy / 29)], -1)
        img = np.clip(img + rng.normal(0, 0.02, img.shape), 0, 1)
        img[120:260, 150 + 10 * k : 330] = (0.2, 0.3, 0.9)
        panels.append((f"panel {k}", (img * 255).astype(np.uint8)))
    return sheet_image(panels, title="scene / method / view", lines=["s_sem 1.000  s_geo 0.925  s_str 0.854"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=10)
    args = ap.parse_args()
    import zlib

    from r360gpu.report import png
    from r360gpu.report.contact_sheets import encode_png

    sheet = make_sheet(np.random.default_rng(0))
    bgr = cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR)
    up = [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP] if hasattr(cv2, "IMWRITE_PNG_FILTER") else []
    ways = {
        "OpenCV level 6, adaptive filters": lambda: cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 6])[1],
        "OpenCV level 1, adaptive filters": lambda: cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1])[1],
        "OpenCV level 1, up filter": lambda: cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 1, *up])[1],
        "report.png, zlib level 1": lambda: np.frombuffer(png.encode(sheet, deflate=zlib), np.uint8),
        f"r360gpu encode_png ({png.DEFLATE})": lambda: np.frombuffer(encode_png(sheet), np.uint8),
    }
    print(f"# one {sheet.shape[1]}x{sheet.shape[0]} contact sheet, best of {args.repeat}; CPU cores: "
          f"{os.cpu_count()}; load average {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"{'encoding':<40}{'ms':>8}{'KB':>8}{'vs level 6':>12}")
    base = None
    for name, fn in ways.items():
        best = np.inf
        for _ in range(args.repeat):
            t = time.perf_counter()
            buf = fn()
            best = min(best, time.perf_counter() - t)
        assert (cv2.imdecode(buf, cv2.IMREAD_COLOR) == bgr).all(), name  # lossless
        base = base or best
        print(f"{name:<40}{best * 1e3:>8.1f}{buf.size / 1024:>8.0f}{base / best:>11.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
