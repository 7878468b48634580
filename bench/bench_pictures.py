"""One view's contact sheet, as `r360gpu score` writes one per method and view, and where its time goes.

Inputs as the scoring pipeline holds them: float32 RGB renders in [0, 1],
float32 depth, a target mask, two probe masks per side.  Timed, best of
``--repeat``, on one thread (the picture writer's):

* the panels with r360gpu's order (float renders resized, then quantised:
  ``report.contact_sheets.rgb8_at``) against the order it replaced (quantised to
  8 bits at full size, then resized), in the same run;
* then the rest of the sheet: laying the panels out, the PNG, the report's
  embedding JPEG.

    python bench/bench_pictures.py [--width 1200 --height 1000] [--repeat 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np


def fake_view(h: int, w: int, rng) -> dict:
    yy, xx = np.mgrid[:h, :w].astype(np.float32)
    base = np.stack([xx / w, yy / h, 0.5 + 0.5 * np.sin(xx / 17 + yy / 29)], -1)
    pre = np.clip(base + rng.normal(0, 0.02, base.shape), 0, 1).astype(np.float32)
    target = ((yy - h / 2) / (h / 5)) ** 2 + ((xx - w / 2) / (w / 6)) ** 2 < 1
    pre[target] = (0.2, 0.3, 0.9)
    post = np.clip(base + rng.normal(0, 0.02, base.shape), 0, 1).astype(np.float32)
    depth_pre = (2 + yy / h).astype(np.float32)
    depth_pre[target] -= 0.5
    depth_post = (2 + yy / h).astype(np.float32)
    delta = np.abs(depth_pre - depth_post)
    blob = lambda cy, cx, r: ((yy - cy) ** 2 + (xx - cx) ** 2 < r * r)  # noqa: E731
    masks_pre = np.stack([target, blob(h / 4, w / 4, h / 8)])
    masks_post = np.stack([blob(h / 2, w / 2, h / 12), blob(h / 4, w / 4, h / 8)])
    return dict(pre=pre, post=post, target=target, delta=delta, threshold=0.25, changed=delta > 0.25,
                semantic_pre=target, semantic_post=blob(h / 2, w / 2, h / 20),
                structural=[("SAM on I_pre", pre, masks_pre), ("SAM on I_post", post, masks_post)])


def best(fn, repeat: int) -> float:
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return min(ts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width", type=int, default=1200)
    ap.add_argument("--height", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    cv2.setNumThreads(1)  # the picture writer is one thread beside the scoring ones
    from r360gpu.report import contact_sheets as P
    from r360gpu.report.embed import EMBED_WIDTH, embed_jpeg

    view = fake_view(args.height, args.width, np.random.default_rng(0))
    width = P.panel_width_for(args.width)

    def panels():
        return P.view_panels(P.SheetView(**view), width=width)

    ours = best(panels, args.repeat)
    keep = P.rgb8_at
    P.rgb8_at = lambda image, w, what="image": P._resize_rgb(P.as_rgb8(image, what), w)
    try:
        before = best(panels, args.repeat)
    finally:
        P.rgb8_at = keep
    ps = panels()
    sheet = P.sheet_image(ps, panel_width=width, title="scene / method / view", legend=P.legend_items(ps))
    layout = best(lambda: P.sheet_image(ps, panel_width=width, title="scene / method / view",
                                        legend=P.legend_items(ps)), args.repeat)
    png = best(lambda: P.encode_png(sheet), args.repeat)
    bgr = cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR)
    jpeg = best(lambda: embed_jpeg(bgr), args.repeat)
    to = (EMBED_WIDTH, max(1, round(bgr.shape[0] * EMBED_WIDTH / bgr.shape[1])))
    area = best(lambda: cv2.resize(bgr, to, interpolation=cv2.INTER_AREA), args.repeat)
    linear = best(lambda: cv2.resize(bgr, to, interpolation=cv2.INTER_LINEAR), args.repeat)
    grey = np.abs(cv2.resize(bgr, to, interpolation=cv2.INTER_AREA).astype(int)
                  - cv2.resize(bgr, to, interpolation=cv2.INTER_LINEAR)).mean()
    with tempfile.TemporaryDirectory() as tmp:
        whole = best(lambda: P.view_contact_sheet(Path(tmp) / "v.png", width=width, title="scene / method / view",
                                                  embed_cache=Path(tmp) / "embed", **view), args.repeat)
    print(f"# one view's contact sheet, renders {args.width}x{args.height}, panels {width} px wide, "
          f"sheet {sheet.shape[1]}x{sheet.shape[0]}; best of {args.repeat}, one thread, CPU cores: {os.cpu_count()}")
    rows = [
        ("panels, quantised at full size then resized (before)", before, ""),
        ("panels, resized then quantised (rgb8_at)", ours, f"{before / ours:.1f}x"),
        ("layout (sheet_image)", layout, ""),
        ("PNG encode", png, ""),
        ("embedding JPEG", jpeg, ""),
        (f"  its reduction to {EMBED_WIDTH} px: area average", area, ""),
        ("  bilinear (taken below 2x)", linear, f"{area / linear:.1f}x, {grey:.2f} grey levels apart on average"),
        ("whole sheet written (view_contact_sheet)", whole, ""),
    ]
    print(f"{'step':<52}{'ms':>8}")
    for label, seconds, note in rows:
        print(f"{label:<52}{seconds * 1e3:>8.1f}   {note}".rstrip())
    return 0


if __name__ == "__main__":
    sys.exit(main())
