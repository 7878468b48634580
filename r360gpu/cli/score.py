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
    g.add_argument("--no-controls", action="store_true",
                   help="skip the identity and reference controls (the unedited scene and the reference scored "
                        "as methods, never ranked) that give each axis its validity verdict")
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
    add_ray_options(p)
    p.set_defaults(func=run)


def add_ray_options(p) -> None:
    g = p.add_argument_group("Ray (scale-out; needs pip install 'r360gpu[ray]')")
    g.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="score the views as Ray tasks: 'local' starts a Ray instance here, 'auto' joins the cluster "
                        "RAY_ADDRESS names, anything else is a cluster address (HOST:PORT). Every node must see the "
                        "bundles (and probe model files) at the same paths and run the same r360gpu version")
    g.add_argument("--ray-cpus", type=int, metavar="N", default=None,
                   help="CPUs of the instance --ray local starts (default: all)")
    g.add_argument("--ray-gpus-per-task", type=float, metavar="G", default=None,
                   help="GPUs each task asks for (default: 1 when the cluster has GPUs, else 0)")
    g.add_argument("--ray-cpus-per-task", type=float, metavar="C", default=1.0,
                   help="CPUs each task asks for (default 1)")
    g.add_argument("--ray-chunk", type=int, metavar="N", default=None,
                   help="views per task (default: ceil(views / (2 x workers)), at most 16)")


def executor_from_args(args):
    """A RayExecutor for --ray (None without it); the other --ray-* flags need --ray."""
    from ..errors import InputError

    address = args.ray
    if address is None:
        given = [flag for flag, unset in (("--ray-cpus", args.ray_cpus is None),
                                          ("--ray-gpus-per-task", args.ray_gpus_per_task is None),
                                          ("--ray-cpus-per-task", args.ray_cpus_per_task == 1.0),
                                          ("--ray-chunk", args.ray_chunk is None)) if not unset]
        if given:
            raise InputError(f"{', '.join(given)} need(s) --ray")
        return None
    from ..pipeline.distributed import RayExecutor, RayOptions, import_ray

    import_ray()  # says how to install it before any work starts
    if args.ray_cpus is not None and address != "local":
        raise InputError("--ray-cpus sizes the instance --ray local starts; a cluster has its own size")
    opts = RayOptions(address=address, cpus=args.ray_cpus, gpus_per_task=args.ray_gpus_per_task,
                      cpus_per_task=args.ray_cpus_per_task, chunk=args.ray_chunk)
    return RayExecutor(opts, adapter=args.adapter)


def options_from_args(args):
    from ..pipeline import EvaluateOptions
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
        controls=not args.no_controls,
        n_boot=args.n_boot,
        n_perm=args.n_perm,
        seed=args.seed,
    )


BUILTIN_SPECS = ("builtin", "builtin-appearance", "builtin-graphseg", "builtin-slic")


def probe_from_spec(spec: str, axis: str):
    """A probe from a command-line spec; ``builtin`` is the weight-free default of the axis."""
    from ..errors import InputError
    from ..probes.registry import parse_probe_spec

    s = spec.strip().lower()
    if s in BUILTIN_SPECS:
        if axis == "semantic":
            if s not in ("builtin", "builtin-appearance"):
                raise InputError(f"probe spec {spec!r} is a structural probe, not a semantic one")
            from ..probes.builtin_semantic import BuiltinAppearanceProbe

            return BuiltinAppearanceProbe()
        from ..probes.builtin_structural import BuiltinStructuralProbe, StructuralParams

        if s == "builtin-appearance":
            raise InputError(f"probe spec {spec!r} is a semantic probe, not a structural one")
        return BuiltinStructuralProbe(StructuralParams.slic() if s == "builtin-slic" else None)
    probe = parse_probe_spec(spec)
    if probe.kind != axis:
        raise InputError(f"probe spec {spec!r} gives a {probe.kind} probe, but --{axis}-probe needs a {axis} one")
    return probe


def probes_from_args(args):
    sem = [probe_from_spec(s, "semantic") for s in args.semantic_probe] if args.semantic_probe else None
    stru = [probe_from_spec(s, "structural") for s in args.structural_probe] if args.structural_probe else None
    return sem, stru


def score_and_report(bundles, out, args) -> int:
    from ..pipeline import evaluate
    from ..report.outputs import summary_lines, write_outputs

    sem, stru = probes_from_args(args)
    results = evaluate(bundles, out=out, semantic_probes=sem, structural_probes=stru,
                       options=options_from_args(args), adapter=args.adapter, force=args.force,
                       progress=not args.quiet, executor=executor_from_args(args) if hasattr(args, "ray") else None)
    paths = write_outputs(results, out)
    for line in summary_lines(results):
        print(line)
    print(f"\nreport: {paths['html']}")
    print(f"results: {paths['json']}  ({paths['csv'].name}, {paths['md'].name}, {paths['tex'].name})")
    return 0


def run(args) -> int:
    return score_and_report([Path(b) for b in args.bundles], Path(args.out), args)
