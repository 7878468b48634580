"""``r360gpu demo``: generate the built-in synthetic benchmark and score it."""
from __future__ import annotations

import time

from .score import add_processes_option, add_scoring_options, options_from_args, processes_from_args, score_and_report


def register(sub) -> None:
    p = sub.add_parser(
        "demo",
        help="generate the built-in synthetic benchmark and score it (the main job on the embedded data)",
        description="Write procedural 3DGS scenes (pre, reference, and simulated removal methods with known "
                    "failure modes) as real .ply files with cameras and masks, then score them like "
                    "'r360gpu score' with the weight-free built-in probes, and print where the report is.",
    )
    p.add_argument("--out", default="r360-demo", metavar="DIR", help="output folder (default ./r360-demo)")
    p.add_argument("--n-views", type=int, default=16, help="views per scene (default 16)")
    p.add_argument("--width", type=int, default=480, help="render width (default 480)")
    p.add_argument("--height", type=int, default=360, help="render height (default 360)")
    p.add_argument("--scene-seed", type=int, default=0, help="seed of the procedural scenes (default 0)")
    p.add_argument("--layouts", action="store_true",
                   help="also write each scene in the layouts of docs/your-scene.md (INRIA output folder, gsplat "
                        "output, nerfstudio export, public Remove360 layout) under OUT/layouts")
    add_scoring_options(p)
    add_processes_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..gpu import get_context
    from ..render.kept import KeptRenders
    from ..synthetic import generate_benchmark

    from ..util.outdir import check_output_folder

    out = check_output_folder(args.out)  # before any work
    check_output_folder(out / "report")
    options_from_args(args)  # every option checked before the benchmark is generated
    executor = processes_from_args(args)
    t = time.perf_counter()
    print(f"generating the synthetic benchmark in {out / 'benchmark'} ...")
    reused: list = []
    kept = KeptRenders()  # the reference renders the masks are drawn from: scoring needs them again
    bundles = generate_benchmark(out / "benchmark", seed=args.scene_seed, n_views=args.n_views,
                                 width=args.width, height=args.height, progress=not args.quiet,
                                 reuse=True, reused=reused, kept=kept,
                                 ctx=get_context(args.adapter))  # scoring's context: its renders are kept
    unchanged = f" ({', '.join(reused)} unchanged since the last run: kept)" if reused else ""
    print(f"  {len(bundles)} scenes in {time.perf_counter() - t:.1f} s{unchanged}")
    if args.layouts:
        from ..synthetic.layouts import write_layouts

        t = time.perf_counter()
        for bundle in bundles:
            write_layouts(bundle, out / "layouts", ctx=get_context(args.adapter))
        print(f"  the scenes also as an INRIA output folder, a gsplat output, a nerfstudio export and public "
              f"Remove360 folders in {out / 'layouts'} ({time.perf_counter() - t:.1f} s)")
    return score_and_report(bundles, out / "report", args, executor=executor, kept=kept)
