"""``r360gpu score``: score scene bundles end to end and write the report."""
from __future__ import annotations

from pathlib import Path


def add_scoring_options(p) -> None:
    """Options shared by ``score`` and ``demo``."""
    g = p.add_argument_group("probes")
    g.add_argument("--semantic-probe", action="append", metavar="SPEC", default=None,
                   help="semantic probe (repeatable; several = 'most alarming' reading). "
                        "'builtin' (default: weight-free appearance probe), 'gsam2-json:DIR', 'png:DIR', "
                        "'grounded:dino=PATH,tokenizer=PATH,sam-encoder=PATH,sam-decoder=PATH'")
    g.add_argument("--structural-probe", action="append", metavar="SPEC", default=None,
                   help="structural probe (repeatable). 'builtin' (default: graph segmentation), "
                        "'sam-json:DIR', 'sam:encoder=PATH,decoder=PATH'")
    g = p.add_argument_group("protocol")
    g.add_argument("--reference-free", action="store_true",
                   help="s_str = 1 - sim(pre, post) even when a reference exists")
    g.add_argument("--compat", action="store_true",
                   help="geometric axis with the public reference code's 8-bit PNG quantisation")
    g.add_argument("--xi", type=float, nargs="+", default=[0.3, 0.5, 0.7, 0.9], metavar="XI",
                   help="acc_seg thresholds to report (0.3 is s_sem; default 0.3 0.5 0.7 0.9)")
    g.add_argument("--depth", choices=["expected", "median"], default=None,
                   help="rendered depth used for the geometric axis (default: the bundle's, else expected)")
    g.add_argument("--views", nargs="+", metavar="PATTERN", default=None,
                   help="score only views whose name matches one of these glob patterns")
    g.add_argument("--lpips", metavar="ONNX", default=None, help="LPIPS ONNX model (else LPIPS is not computed)")
    g.add_argument("--no-boundary", action="store_true", help="skip the mask erosion/dilation sweep")
    g.add_argument("--no-pictures", action="store_true", help="skip per-view contact sheets")
    g = p.add_argument_group("statistics")
    g.add_argument("--n-boot", type=int, default=20000, help="bootstrap resamples (default 20000)")
    g.add_argument("--n-perm", type=int, default=5000, help="permutations (default 5000)")
    g.add_argument("--seed", type=int, default=0, help="seed of bootstrap and permutations (default 0)")
    g = p.add_argument_group("run")
    g.add_argument("--adapter", default=None, help="GPU adapter: auto, gpu, cpu, or part of its name")
    g.add_argument("--force", action="store_true", help="recompute everything (ignore cached per-view results)")
    g.add_argument("--quiet", action="store_true", help="no progress bars")


def register(sub) -> None:
    p = sub.add_parser(
        "score",
        help="score scene bundles (render, probe, measure, aggregate, report)",
        description="Render every evaluation view of each bundle (pre, reference, each method), run the "
                    "probes, compute the semantic, geometric and structural axes, RQS, ranks and statistics, "
                    "and write results.json, results.csv, tables.md/.tex, pictures and report.html to --out. "
                    "A killed run resumes where it stopped.",
    )
    p.add_argument("bundles", nargs="+", metavar="BUNDLE", help="scene bundle folders (with scene.toml)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    add_scoring_options(p)
    p.set_defaults(func=run)


def options_from_args(args):
    from ..scoring import EvaluateOptions
    from ..errors import InputError

    for x in args.xi:
        if not 0.0 < x <= 1.0:
            raise InputError(f"--xi values must lie in (0, 1], got {x}")
    return EvaluateOptions(
        xis=tuple(sorted(set(args.xi) | {0.3})),
        compat=args.compat,
        reference_free=True if args.reference_free else None,
        depth=args.depth,
        views=tuple(args.views) if args.views else None,
        boundary=not args.no_boundary,
        lpips_model=args.lpips,
        pictures=not args.no_pictures,
        n_boot=args.n_boot,
        n_perm=args.n_perm,
        seed=args.seed,
    )


def probe_from_spec(spec: str, axis: str):
    """A probe from a command-line spec; ``builtin`` is the weight-free default of the axis."""
    from ..probes.registry import probe_for_axis

    return probe_for_axis(spec, axis)


def probes_from_args(args):
    sem = [probe_from_spec(s, "semantic") for s in args.semantic_probe] if args.semantic_probe else None
    stru = [probe_from_spec(s, "structural") for s in args.structural_probe] if args.structural_probe else None
    return sem, stru


def score_and_report(bundles, out, args) -> int:
    from ..scoring import evaluate
    from ..report.outputs import summary_lines, write_outputs

    sem, stru = probes_from_args(args)
    results = evaluate(bundles, out=out, semantic_probes=sem, structural_probes=stru,
                       options=options_from_args(args), adapter=args.adapter, force=args.force,
                       progress=not args.quiet)
    paths = write_outputs(results, out)
    for line in summary_lines(results):
        print(line)
    print(f"\nreport: {paths['html']}")
    print(f"results: {paths['json']}  ({paths['csv'].name}, {paths['md'].name}, {paths['tex'].name})")
    return 0


def run(args) -> int:
    return score_and_report([Path(b) for b in args.bundles], Path(args.out), args)
