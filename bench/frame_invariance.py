"""Every 3D output of the synthetic room, unframed vs every splat file moved by one similarity and its
frame declared: they must be equal.

    ./r360 python bench/frame_invariance.py [--views 6] [--size 240x180] [--detail 0.25] [--orbit 4] [--seed 1]

Writes two bundles (``room`` as generated, ``room_framed`` moved by a random similarity, scale
log-uniform in [0.1, 10], declared by a ``dataparser_transforms.json`` named by scene.toml's
``frame``), then per bundle: a ``[target]`` of the masks of 4 views lifted over pre (Gaussians lifted,
of them the target's, rendered target masks) and one of the target's indices (masks rendered at every
view), ``score --orbit N --residuals --prune-residuals
(floater count)`` (capture axes, orbit poses kept and their axes, residual maximum and top
indices, pruned axes), and the viewer's live acc_depth at the first evaluation view.  Prints
one line per output, framed vs unframed.  ``--bundles DIR`` reuses bundles made before (e.g. to
score them with another checkout's code: the scoring uses public APIs only).
"""
from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

LIFT_VIEWS = 4
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # with_target, shared with the frame tests


def make_bundles(folder: Path, args) -> None:
    from r360gpu.synthetic import generate_benchmark
    from r360gpu.synthetic.frames import moved_bundle, random_similarity

    w, h = (int(v) for v in args.size.split("x"))
    src = generate_benchmark(folder / "gen", scenes=("room",), methods=("clean", "floaters"), seed=0,
                             n_views=args.views, width=w, height=h, detail=args.detail)[0]
    shutil.copytree(src, folder / "room")
    frame = random_similarity(np.random.default_rng(args.seed))
    moved_bundle(src, folder / "room_framed", frame)
    print(f"frame: scale {frame.scale:.4g}, translation {np.round(frame.translation, 3).tolist()}")


def with_target(bundle_dir: Path, out: Path, indices=None) -> Path:
    """A copy whose scene.toml has no masks but a [target]: LIFT_VIEWS views' masks, or ``indices``."""
    from frame_outputs import with_target as shared

    return shared(bundle_dir, out, indices, views=LIFT_VIEWS)


def outputs(bundle_dir: Path, work: Path, args, ctx) -> dict:
    from r360gpu.bundle import load_bundle
    from r360gpu.io import load_gaussians, load_mask
    from r360gpu.lift.resolve import resolve_target
    from r360gpu.pipeline import EvaluateOptions, evaluate
    from r360gpu.render.sources import open_source
    from r360gpu.synthetic import make_scene
    from r360gpu.viewer.layers import build_layers
    from r360gpu.viewer.live import live_axis

    w, h = (int(v) for v in args.size.split("x"))
    scene = make_scene("room", n_views=args.views, width=w, height=h, detail=args.detail)
    n_bg, n_pre = scene.background.n, scene.pre.n
    out: dict = {}
    tb = load_bundle(with_target(bundle_dir, work / "target"))
    pre = open_source(tb.pre, ctx=ctx)
    try:
        resolved, record = resolve_target(tb, pre, ctx=ctx)
    except Exception as e:  # the failure is the figure (main refuses some framed targets)
        out["lift"] = f"error: {e}"
    else:
        import inspect

        from r360gpu.lift.resolve import lifted_target

        # a checkout whose lifted_target takes no frame lifts with the cameras as they are
        kw = {"frame": pre.frame} if "frame" in inspect.signature(lifted_target).parameters else {}
        lifted, _ = lifted_target(tb, pre.gaussians, ctx=ctx, options=pre.render_options, **kw)
        idx = lifted.indices
        out["lifted"] = (len(idx), int(np.count_nonzero((idx >= n_bg) & (idx < n_pre))))
        out["lifted_indices"] = idx
        out["target_masks"] = {v: resolved.masks[v] for v in record["rendered"]}
    finally:
        pre.release()
    ib = load_bundle(with_target(bundle_dir, work / "indices", np.arange(n_bg, n_pre)))
    pre = open_source(ib.pre, ctx=ctx)
    try:
        out["indices_masks"] = resolve_target(ib, pre, ctx=ctx)[0].masks
    except Exception as e:
        out["indices_masks"] = f"error: {e}"
    finally:
        pre.release()
    bundle = load_bundle(bundle_dir)
    n_floaters = load_gaussians(bundle.methods["floaters"].path).n - n_bg
    opts = EvaluateOptions(n_boot=200, n_perm=100, pictures=False, boundary=False, orbit=args.orbit,
                           residuals=True, prune_residuals=n_floaters)
    res = evaluate(bundle, out=work / "out", device=ctx, progress=False, options=opts)["scenes"]["room"]
    out["axes"] = {m: res["methods"][m]["axes"] for m in res["methods"]}
    orbit = res.get("orbit", {})
    out["orbit_kept"] = [v["view"] for v in next(iter(orbit.get("methods", {}).values()), {}).get("views", [])]
    out["orbit_axes"] = {m: e["axes"] for m, e in orbit.get("methods", {}).items()}
    out["residual_max"] = {m: e.get("max") for m, e in res.get("residuals", {}).items()}
    out["residual_top"] = {m: e.get("top") for m, e in res.get("residuals", {}).items()}
    out["pruned_axes"] = {m: e.get("axes") for m, e in res.get("pruned", {}).items()}
    layers = build_layers(bundle, ctx)
    try:
        view = bundle.views[0]
        cam = bundle.cameras[view]
        mask = load_mask(bundle.masks[view], shape=(cam.height, cam.width))
        live = live_axis(ctx, layers["pre"].image(cam, view), layers["floaters"].image(cam, view), mask, "evaluation")
        out["live_acc_depth"] = live.acc_depth
    finally:
        for layer in layers.values():
            layer.release()
    return out


def max_diff(a, b) -> float:
    """The largest |a - b| over every number of two trees (inf when they differ in shape)."""
    from frame_outputs import axes_diff

    return axes_diff(a, b)[0]


def _short(entry) -> str:
    """An axes entry as its RQS and three axes (3 decimals); anything else as it is."""
    if not isinstance(entry, dict):
        return str(entry)
    return " ".join(f"{k} {entry[k]:.3f}" if isinstance(entry.get(k), float) else f"{k} {entry.get(k)}"
                    for k in ("s_sem", "s_geo", "s_str", "rqs"))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--views", type=int, default=6)
    p.add_argument("--size", default="240x180")
    p.add_argument("--detail", type=float, default=0.25)
    p.add_argument("--orbit", type=int, default=4)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--bundles", type=Path, help="reuse room/ and room_framed/ made in this folder before")
    p.add_argument("--keep", type=Path, help="make the bundles here (kept) instead of a temporary folder")
    args = p.parse_args()
    from r360gpu.gpu import get_context

    ctx = get_context()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.bundles or args.keep or Path(tmp)
        if args.bundles is None:
            make_bundles(folder, args)
        work = Path(tmp) / "work"
        plain = outputs(folder / "room", work / "plain", args, ctx)
        framed = outputs(folder / "room_framed", work / "framed", args, ctx)
    print(f"{'output':<22} {'unframed':<40} framed")
    for key in ("lift", "lifted"):
        if key in plain or key in framed:
            print(f"{key:<22} {str(plain.get(key)):<40} {framed.get(key)}")
    if "lifted_indices" in plain and "lifted_indices" in framed:
        print(f"{'lifted set equal':<22} {np.array_equal(plain['lifted_indices'], framed['lifted_indices'])}")
    if "target_masks" in plain and "target_masks" in framed:
        a, b = plain["target_masks"], framed["target_masks"]
        diff = sum(int(np.count_nonzero(a[v] != b.get(v, ~a[v]))) for v in a)
        print(f"{'target mask pixels':<22} differing: {diff} over {len(plain['target_masks'])} rendered views")
    a, b = plain["indices_masks"], framed["indices_masks"]
    if isinstance(a, dict) and isinstance(b, dict):
        diff = sum(int(np.count_nonzero(a[v] != b[v])) for v in a)
        print(f"{'indices target masks':<22} differing pixels: {diff} over {len(a)} views")
    else:
        print(f"{'indices target masks':<22} {str(a)[:38]:<40} {str(b)[:200]}")
    print(f"{'orbit poses kept':<22} {str(plain['orbit_kept']):<40} {framed['orbit_kept']}")
    for key in ("axes", "orbit_axes", "pruned_axes", "residual_max"):
        print(f"{key:<22} max |framed - unframed| over every number = {max_diff(plain[key], framed[key]):.3g}")
        for m in plain[key]:
            print(f"  {m:<20} {_short(plain[key][m]):<40} {_short(framed[key].get(m))}")
    for m, top in plain["residual_top"].items():
        same = top == framed["residual_top"].get(m)
        print(f"{'residual top ' + m:<22} identical ranking: {same}")
    print(f"{'viewer live acc_depth':<22} {str(plain['live_acc_depth']):<40} {framed['live_acc_depth']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
