"""Frame invariance over many unseen frames: every 3D output of a framed room against the unframed one.

    ./r360 python bench/frame_invariance_sweep.py --draws 20 --seed0 1000 [--undone] [--ulp 2] [--no-layouts]

The synthetic room of ``tests/test_frame_invariance.py`` (clean and floaters, 5 views at 160x120,
detail 0.25) is scored once as generated, then once per frame with every splat file moved into it
and the frame declared, and every 3D output is compared with the unframed run by the test's own
code (tests/frame_outputs.py: `outputs`, `compare`, `failures`): the lifted ``[target]``, its target
masks, the target masks of a ``[target]`` of indices, the orbit poses kept and their poses,
residuals (top ranking, every value, the residual PLY's coordinates), the viewer's live acc_depth,
and the axes of the capture views, the orbit and the pruned what-if (s_sem and s_geo to 1e-6, the
other numbers to AXES_TOL).  The frames:

* ``--draws N`` similarities, seeds ``--seed0`` .. ``--seed0 + N - 1``
  (`frame_outputs.sweep_frame`: a random rotation, scale 0.1 / 10 / log-uniform in between, a
  shift of 0.1 to 100 scene radii), declared as nerfstudio does (``moved_bundle``); with
  ``--undone`` each is also compared with the run of its own float32 files moved back into the
  cameras' world in float64, no frame (`frame_outputs.undone_bundle`): a check that fails against
  the unframed run but holds against that one fails from the files' float32 rounding, not from the
  frame handling;
* unless ``--no-layouts``, the user's own layouts of `r360gpu.synthetic.layouts`: **gsplat**
  (``frame = "gsplat"``, recomputed from the COLMAP model and its sparse points), **nerfstudio**
  (``transforms.json`` cameras, a dataparser transform beside each export) and **nerfstudio-applied**
  (the same with the ``applied_transform`` ns-process-data records in ``transforms.json``, the
  dataparser transform including it, as nerfstudio writes them);
* ``--ulp K`` reference rows with no frame at all: every centre moved to a random float32
  neighbour (``bench/frame_precision.py``), the rounding any float32 file carries.

One row per frame (``rounding``: `frame_outputs.file_rounding`, how far storing the moved centres as
float32 moved one, in the cameras' units; ``fails``: the checks failed against the unframed run;
``vs undone``: against the undone run), then a summary: how many frames pass each check, the
largest difference, and the file rounding below which every frame passes every check.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))  # the comparison shared with tests/test_frame_invariance.py
sys.path.insert(0, str(ROOT / "bench"))

from frame_outputs import (AXES_KINDS, AXES_TOL, POSE_TOL, RESIDUAL_TOL, compare, failures,  # noqa: E402
                           file_rounding, make_room, nerfstudio_applied, outputs, rewritten, scene_radius,
                           sweep_frame, ulp_moved, undone_bundle)

#: (column title, width, the check's text from a compare result)
COLUMNS = (
    ("rounding", 8, lambda c: f"{c['rounding']:.1e}"),
    ("lifted", 10, lambda c: f"{c['n_lifted']} {'=' if c['lifted'] else 'X'}"),
    ("mask px", 7, lambda c: str(c["mask_pixels"])),
    ("idx px", 6, lambda c: str(c["indices_pixels"])),
    ("orbit", 5, lambda c: f"{c['n_orbit']} {'=' if c['orbit_kept'] else 'X'}"),
    ("pose", 8, lambda c: f"{c['pose']:.1e}"),
    ("top", 3, lambda c: "=" if c["top"] else "X"),
    ("resid", 8, lambda c: f"{c['residual']:.1e}"),
    ("ply", 3, lambda c: "=" if c["residual_ply"] else "X"),
    ("live", 8, lambda c: f"{c['live']:.1e}"),
    ("sem/geo", 8, lambda c: f"{c['exact']:.1e}"),
    ("axes", 8, lambda c: f"{c['axes'][0]:.1e}"),
    ("orbit ax", 8, lambda c: f"{c['orbit_axes'][0]:.1e}"),
    ("pruned ax", 9, lambda c: f"{c['pruned_axes'][0]:.1e}"),
)
#: (summary line, the check's figure from a compare result, its bound)
SUMMARY = (
    ("lifted set identical", lambda c: 0.0 if c["lifted"] else 1.0, 0.0),
    ("lifted target masks: differing pixels", lambda c: c["mask_pixels"], 0.0),
    ("indices target masks: differing pixels", lambda c: c["indices_pixels"], 0.0),
    ("orbit poses kept identical", lambda c: 0.0 if c["orbit_kept"] else 1.0, 0.0),
    ("orbit camera poses: max |diff|", lambda c: c["pose"], POSE_TOL),
    ("residual top ranking identical", lambda c: 0.0 if c["top"] else 1.0, 0.0),
    ("residuals: max |diff|", lambda c: c["residual"], RESIDUAL_TOL),
    ("residual PLY in the file's coordinates", lambda c: 0.0 if c["residual_ply"] else 1.0, 0.0),
    ("viewer live acc_depth: |diff|", lambda c: c["live"], POSE_TOL),
    ("s_sem, s_geo (every axes entry): max |diff|", lambda c: c["exact"], 1e-6),
    *((f"{k}: other numbers' max |diff|", (lambda k: lambda c: c[k][0])(k), AXES_TOL) for k in AXES_KINDS),
)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=20, help="random similarities (default 20)")
    p.add_argument("--seed0", type=int, default=1000, help="the first draw's seed (default 1000)")
    p.add_argument("--undone", action="store_true",
                   help="also compare each similarity with its files moved back in float64, no frame")
    p.add_argument("--ulp", type=int, default=0, help="no-frame rows with centres moved by <= 1 float32 ulp")
    p.add_argument("--no-layouts", action="store_true", help="skip the gsplat and nerfstudio layouts")
    p.add_argument("--keep", type=Path, help="work in this folder (kept) instead of a temporary one")
    args = p.parse_args()
    from r360gpu.bundle import load_bundle
    from r360gpu.gpu import get_context
    from r360gpu.io import load_gaussians
    from r360gpu.synthetic.frames import moved_bundle
    from r360gpu.synthetic.layouts import write_layouts

    ctx = get_context()
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)

        def quiet(f, *a):
            """f(*a) without the scoring's progress lines (the frames it applies)."""
            with contextlib.redirect_stdout(io.StringIO()):
                return f(*a)

        folder, n_floaters, target = quiet(make_room, root / "gen", ctx)
        plain = quiet(outputs, folder, root / "plain", ctx, n_floaters, target)
        plain_rounding = file_rounding(folder)
        radius = scene_radius(load_gaussians(load_bundle(folder).pre.path).means)
        print(f"unframed: lifted {len(plain['lifted'])}, {len(plain['orbit'])} orbit poses kept, scene radius "
              f"{radius:.3g}; bounds: pose/live {POSE_TOL:g}, residual {RESIDUAL_TOL:g}, s_sem/s_geo 1e-06, "
              f"other axes {AXES_TOL:g} ('=' identical, 'X' differs)")

        def frames():
            for seed in range(args.seed0, args.seed0 + args.draws):
                frame = sweep_frame(seed, radius)
                shift = np.linalg.norm(frame.translation) / (frame.scale * radius)
                yield (f"seed {seed}", f"s {frame.scale:.3g} t {shift:.3g}r",
                       lambda d, f=frame: moved_bundle(folder, d, f), frame)
            if not args.no_layouts:
                made = write_layouts(folder, root / "layouts", layouts=("gsplat", "nerfstudio"), ctx=ctx)
                for layout in ("gsplat", "nerfstudio"):
                    b = load_bundle(made[layout][0])
                    yield layout, f"s {b.pre.frame.scale:.3g}", lambda d, x=made[layout][0]: x, None
                yield ("nerfstudio-applied", "applied_transform",
                       lambda d: nerfstudio_applied(made["nerfstudio"][0], d), None)
            for seed in range(args.ulp):
                yield f"ulp {seed}", "no frame, 1 ulp", lambda d, s=seed: rewritten(
                    folder, d, lambda rel: ulp_moved(load_gaussians(folder / rel), np.random.default_rng(s))), None

        head = (f"{'frame':<19} {'similarity':<17} " + " ".join(f"{t:>{w}}" for t, w, _ in COLUMNS)
                + "  time  fails | vs undone")
        print(head, flush=True)
        rows = []
        for i, (name, what, make, frame) in enumerate(frames()):
            start = time.perf_counter()
            moved = make(root / f"framed{i}")
            out = quiet(outputs, moved, root / f"out{i}", ctx, n_floaters, target)
            c = compare(out, plain)
            c["rounding"] = file_rounding(moved)
            bad = failures(c)
            against = None
            if args.undone and frame is not None:
                back = undone_bundle(folder, moved, frame, root / f"undone{i}")
                against = failures(compare(out, quiet(outputs, back, root / f"outu{i}", ctx, n_floaters, target)))
            rows.append((name, c, bad, against))
            print(f"{name:<19} {what:<17} " + " ".join(f"{f(c):>{w}}" for _, w, f in COLUMNS)
                  + f" {time.perf_counter() - start:4.0f}s  {', '.join(bad) or '-'}"
                  + ("" if against is None else f" | {', '.join(against) or '-'}"), flush=True)
        framed = [r for r in rows if not r[0].startswith("ulp")]
        print(f"\nsummary over {len(framed)} frames ({args.draws} similarities, seeds {args.seed0}.."
              f"{args.seed0 + args.draws - 1}{'' if args.no_layouts else ', 3 layouts'}):")
        for title, figure, bound in SUMMARY:
            values = [figure(c) for _, c, _, _ in framed]
            ok = sum(v <= bound for v in values)
            print(f"  {title:<48} {ok}/{len(values)} pass, largest {max(values, default=0.0):.3g}")
        for k in AXES_KINDS:
            values = sorted(c[k][0] for _, c, _, _ in framed)
            if values:
                worst = max(framed, key=lambda r: r[1][k][0])
                print(f"  {k} other numbers' max |diff| over the frames: median {np.median(values):.2g}, "
                      f"largest {values[-1]:.2g} ({worst[0]}: {worst[1][k][1]})")
        failed = [f"{n} ({', '.join(b)})" for n, _, b, _ in framed if b]
        print(f"  frames failing a check: {len(failed)}" + (": " + "; ".join(failed) if failed else ""))
        passing = [d for _, c, b, _ in framed if not b for d in [c["rounding"]]]
        failing = [d for _, c, b, _ in framed if b for d in [c["rounding"]]]
        print(f"  file rounding of the frames passing every check: up to {max(passing, default=0.0):.2g}; "
              f"of those failing one: from {min(failing, default=float('inf')):.2g} "
              f"(the unframed file's own: {plain_rounding:.2g})")
        if args.undone:
            undone_rows = [(n, a) for n, _, _, a in framed if a is not None]
            worse = [f"{n} ({', '.join(a)})" for n, a in undone_rows if a]
            print(f"  similarities failing a check against their undone files: {len(worse)} of {len(undone_rows)}"
                  + (": " + "; ".join(worse) if worse else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
