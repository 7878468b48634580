"""``r360gpu score``: score scene bundles end to end and write the report."""
from __future__ import annotations

from pathlib import Path

from ..protocol import N_BOOT, N_PERM, XI_DEFAULT, XI_SWEEP
from .frame_option import add_frame_option
from .lists import ListAction, add_views_option


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
    g.add_argument("--probe-device", default="auto", metavar="DEVICE", type=str.lower,
                   help="onnxruntime execution provider of the learned probes (sam:, grounded:) and LPIPS: "
                        "auto (default: a GPU provider for the renderer's GPU when the installed onnxruntime has "
                        "one, else cpu), cpu, cuda, tensorrt, webgpu, directml, coreml; a spec's device= wins. "
                        "A provider named here that onnxruntime lacks is an error; one that cannot start is a "
                        "warning naming what ran. GPU providers: pip install 'r360gpu[gpu-cuda]' or "
                        "'r360gpu[gpu-webgpu]'")
    g = p.add_argument_group("protocol")
    g.add_argument("--reference-free", action="store_true",
                   help="s_str = 1 - sim(pre, post) even when a reference exists")
    g.add_argument("--compat", nargs="?", const="public", default=None, type=_compat_mode, metavar="MODE",
                   help="score as the public Remove360 scripts do: 'public' (the default of --compat: their "
                        "save_intermediate=True depth path) or 'public-default' (their default path, which "
                        "marks SMALL depth changes); on a public folder every axis is the scripts' number")
    g.add_argument("--xi", action=ListAction, item_type=float, default=None, metavar="XI",
                   help=f"acc_seg threshold to report; repeat the flag or give a comma list ({XI_DEFAULT:g} is "
                        f"s_sem and always reported; default {','.join(f'{x:g}' for x in XI_SWEEP)})")
    g.add_argument("--depth", choices=["expected", "median"], default=None,
                   help="rendered depth used for the geometric axis (default: the bundle's, else expected)")
    g.add_argument("--antialiased", action="store_true",
                   help="render every splat scene in the antialiased mode (scenes trained with gsplat "
                        "rasterize_mode='antialiased', INRIA antialiasing=True or Mip-Splatting); per source: "
                        "antialiased = true in scene.toml")
    add_views_option(g)
    g.add_argument("--lpips", metavar="ONNX", default=None, help="LPIPS ONNX model (else LPIPS is not computed)")
    g.add_argument("--orbit", type=int, default=0, metavar="N",
                   help="also score N cameras around the lifted target (splat scenes; results under "
                        "scenes.S.orbit, never mixed into the capture-view axes)")
    g.add_argument("--orbit-radius", type=float, default=1.0, metavar="X",
                   help="the orbit's radius as a multiple of the capture cameras' median distance to the target "
                        "(default 1; poses that would leave the capture's bounds are brought nearer)")
    g.add_argument("--orbit-elevation", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                   help="the orbit's elevations in degrees above the capture's horizon (default: the span of "
                        "the capture cameras')")
    g.add_argument("--orbit-azimuth", type=float, nargs=2, default=(0.0, 360.0), metavar=("FROM", "TO"),
                   help="the orbit's azimuths in degrees around the capture's up, 0 toward the first capture "
                        "camera (default 0 360: all the way round)")
    g.add_argument("--residuals", action="store_true",
                   help="write residuals/SCENE/METHOD.ply: each splat method's Gaussians with a 'residual' "
                        "property (their weight in the target region of the views that flag evidence)")
    g.add_argument("--prune-residuals", type=_prune_amount, default=None, metavar="Q",
                   help="also score each splat method without its top residual Gaussians, as METHOD+pruned: "
                        "Q a count (integer >= 1) or a fraction of the method's Gaussians (0 < Q < 1); a "
                        "what-if shown beside the method, never ranked (implies --residuals)")
    g.add_argument("--no-boundary", action="store_true", help="skip the mask erosion/dilation sweep")
    g.add_argument("--no-pictures", action="store_true", help="skip per-view contact sheets")
    g.add_argument("--no-controls", action="store_true",
                   help="skip the identity and reference controls (the unedited scene and the reference scored "
                        "as methods, never ranked) that give each axis its validity verdict")
    g = p.add_argument_group("statistics")
    g.add_argument("--n-boot", type=int, default=N_BOOT, help=f"bootstrap resamples (default {N_BOOT})")
    g.add_argument("--n-perm", type=int, default=N_PERM, help=f"permutations (default {N_PERM})")
    g.add_argument("--seed", type=int, default=0, help="seed of bootstrap and permutations (default 0)")
    g = p.add_argument_group("run")
    g.add_argument("--adapter", default=None,
                   help="GPU adapter: auto, gpu, gpu:N (the N-th GPU), cpu, or part of its name")
    g.add_argument("--force", action="store_true", help="recompute everything (ignore cached per-view results)")
    g.add_argument("--quiet", action="store_true", help="no progress bars")


def _compat_mode(value: str) -> str:
    import argparse

    from ..metrics.compat import COMPAT_MODES

    if value not in COMPAT_MODES:
        raise argparse.ArgumentTypeError(
            f"{value!r} is not a compat mode ({', '.join(COMPAT_MODES)}); --compat takes the next word as its "
            f"mode, so write --compat=public or put --compat after the bundles")
    return value


def register(sub) -> None:
    p = sub.add_parser(
        "score",
        help="score scene bundles (render, probe, measure, aggregate, report)",
        description="Render every evaluation view of each bundle (pre, reference, each method), run the "
                    "probes, compute the semantic, geometric and structural axes, RQS, ranks and statistics, "
                    "and write results.json, results.csv, tables.md/.tex, pictures and report.html to --out. "
                    "A killed run resumes where it stopped.",
    )
    p.add_argument("bundles", nargs="*", metavar="BUNDLE",
                   help="scene bundle folders (scene.toml or the public Remove360 layout), or METHOD=FOLDER: "
                        "public-layout folders of one scene, one per method, grouped into one scene by folder "
                        "name (e.g. GC=runs/gc/bedroom_table AF=runs/af/bedroom_table)")
    p.add_argument("--benchmark", metavar="ROOT", default=None,
                   help="a benchmark root ROOT/<method>/<scene>/ (public-layout folders or bundles): every "
                        "scene with the methods that have it")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    g = p.add_argument_group("inputs")
    g.add_argument("--prompt", default=None,
                   help="category prompt (replaces the bundles'; Remove360 folders: instead of prompt.txt)")
    g.add_argument("--method-name", default=None, metavar="NAME",
                   help="name of a plain Remove360 folder's method (default: 'after')")
    g.add_argument("--scene-name", default=None, metavar="NAME",
                   help="scene name of the METHOD=FOLDER folders (default: the folder name), or of the one "
                        "bundle given")
    add_frame_option(g)
    add_scoring_options(p)
    add_ray_options(p)
    p.set_defaults(func=run)


def add_processes_option(g) -> None:
    g.add_argument("--processes", metavar="N", default=None,
                   help="score the views in N worker processes on this machine, each with its own GPU device "
                        "('auto': one per two cores); default: all in this process, stages overlapped on threads")


def add_ray_options(p) -> None:
    add_processes_option(p.add_argument_group("Parallel scoring on this machine"))
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
    g.add_argument("--ray-timeout", type=float, metavar="SECONDS", default=None,
                   help="seconds a cluster address has to answer before the run stops with an error "
                        "(default 30)")


def processes_from_args(args):
    """A ProcessExecutor for --processes N (N > 1, or 'auto'), else None."""
    from ..errors import InputError

    value = getattr(args, "processes", None)
    if value is None:
        return None
    from ..pipeline.processes import ProcessExecutor, check_workers, default_workers

    if value == "auto":
        workers = default_workers()
    else:
        try:
            workers = int(value)
        except ValueError:
            raise InputError(f"--processes takes a number of worker processes or 'auto', got {value!r}") from None
        check_workers(workers)
    return ProcessExecutor(workers, adapter=args.adapter) if workers > 1 else None


def executor_from_args(args):
    """A RayExecutor for --ray, a ProcessExecutor for --processes (None without them); the other
    --ray-* flags need --ray."""
    from ..errors import InputError

    address = args.ray
    if address is not None and getattr(args, "processes", None) is not None:
        raise InputError("--processes and --ray cannot be combined (Ray places its own workers)")
    if address is None:
        given = [flag for flag, unset in (("--ray-cpus", args.ray_cpus is None),
                                          ("--ray-gpus-per-task", args.ray_gpus_per_task is None),
                                          ("--ray-cpus-per-task", args.ray_cpus_per_task == 1.0),
                                          ("--ray-chunk", args.ray_chunk is None),
                                          ("--ray-timeout", args.ray_timeout is None)) if not unset]
        if given:
            raise InputError(f"{', '.join(given)} need(s) --ray")
        return processes_from_args(args)
    from ..pipeline.distributed import DEFAULT_CONNECT_TIMEOUT, RayExecutor, RayOptions, import_ray, probe_cluster

    timeout = DEFAULT_CONNECT_TIMEOUT if args.ray_timeout is None else args.ray_timeout
    import_ray()  # says how to install it before any work starts
    if args.ray_cpus is not None and address != "local":
        raise InputError("--ray-cpus sizes the instance --ray local starts; a cluster has its own size")
    opts = RayOptions(address=address, cpus=args.ray_cpus, gpus_per_task=args.ray_gpus_per_task,
                      cpus_per_task=args.ray_cpus_per_task, chunk=args.ray_chunk, connect_timeout=timeout)
    probe_cluster(address, opts.connect_timeout)  # an unreachable cluster is said before any work
    return RayExecutor(opts, adapter=args.adapter)


def options_from_args(args):
    from ..pipeline import EvaluateOptions

    xis = args.xi or XI_SWEEP  # checked, with every other option, by EvaluateOptions
    return EvaluateOptions(
        xis=tuple(sorted(set(xis) | {XI_DEFAULT})),
        compat=args.compat,
        reference_free=True if args.reference_free else None,
        depth=args.depth,
        views=tuple(args.views) if args.views else None,
        boundary=not args.no_boundary,
        lpips_model=args.lpips,
        probe_device=args.probe_device,
        pictures=not args.no_pictures,
        controls=not args.no_controls,
        n_boot=args.n_boot,
        n_perm=args.n_perm,
        seed=args.seed,
        antialiased=getattr(args, "antialiased", False),
        orbit=getattr(args, "orbit", 0),
        orbit_radius=getattr(args, "orbit_radius", 1.0),
        orbit_elevation=tuple(args.orbit_elevation) if getattr(args, "orbit_elevation", None) else None,
        orbit_azimuth=tuple(getattr(args, "orbit_azimuth", (0.0, 360.0))),
        residuals=getattr(args, "residuals", False) or getattr(args, "prune_residuals", None) is not None,
        prune_residuals=getattr(args, "prune_residuals", None),
    )


def _prune_amount(text: str):
    """--prune-residuals Q: an integer count, or a fraction written with a point or an exponent."""
    import argparse

    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a count (integer >= 1) or a fraction in (0, 1), got {text!r}")


def probe_from_spec(spec: str, axis: str, device: str = "cpu"):
    """A probe from a command-line spec; ``builtin`` is the weight-free default of the axis; device:
    a learned probe's onnxruntime device when the spec gives none."""
    from ..probes.registry import probe_for_axis

    return probe_for_axis(spec, axis, device)


def probe_device(args) -> str:
    """--probe-device, with auto resolved for the GPU the renderer uses (--adapter)."""
    from ..probes.providers import choose

    if args.probe_device != "auto":
        return choose(args.probe_device)
    from ..gpu import get_context

    return choose("auto", get_context(args.adapter).adapter_info)


def _learned_probes(args) -> bool:
    specs = list(args.semantic_probe or []) + list(args.structural_probe or [])
    return any(str(s).strip().lower().startswith(("sam:", "grounded:")) for s in specs)


def check_probe_device(args) -> None:
    """InputError, before any work, for a --probe-device named explicitly whose provider the installed
    onnxruntime lacks, when a learned probe would use it."""
    from ..probes.providers import plan

    if args.probe_device != "auto" and _learned_probes(args):
        plan(args.probe_device)


def probes_from_args(args):
    device = probe_device(args) if _learned_probes(args) else "cpu"
    sem = [probe_from_spec(s, "semantic", device) for s in args.semantic_probe] if args.semantic_probe else None
    stru = ([probe_from_spec(s, "structural", device) for s in args.structural_probe]
            if args.structural_probe else None)
    return sem, stru


def score_and_report(bundles, out, args, executor=None, kept=None) -> int:
    """evaluate() (which writes every output under ``out``, all together or not at all), then the
    summary and where the files are; ``out`` is locked for the run.  kept: renders made before
    (``evaluate(kept=...)``)."""
    from ..util.filehash import memo_file
    from ..util.outdir import open_output_folder
    from ..util.warning_log import collecting

    with open_output_folder(out), collecting(), memo_file(Path(out) / ".r360hashes.json"):
        return _score_and_report(bundles, Path(out), args, executor, kept)


def _score_and_report(bundles, out, args, executor, kept=None) -> int:
    from ..pipeline.evaluate import Plan, evaluate_plan

    sem, stru = probes_from_args(args)
    plan = Plan.open(out=out, options=options_from_args(args), semantic_probes=sem, structural_probes=stru,
                     device=args.adapter, executor=executor, progress=not args.quiet, kept=kept)
    results = evaluate_plan(bundles, plan, force=args.force)
    # Imported once scoring is done: report.html and report.outputs import matplotlib (0.3 s),
    # which the first view does not need.
    from ..report.html import REPORT_HTML
    from ..report.outputs import summary_lines
    from ..report.results_io import RESULTS_CSV, RESULTS_JSON
    from ..report.results_tables import TABLES_MD, TABLES_TEX

    for line in summary_lines(results):
        print(line)
    print(f"\nreport: {Path(out) / REPORT_HTML}")
    print(f"results: {Path(out) / RESULTS_JSON}  ({RESULTS_CSV}, {TABLES_MD}, {TABLES_TEX})")
    return 0


def start_ahead(adapter: str | None) -> None:
    """What a run needs later, started on threads now, while its inputs are read: the GPU context
    (evaluate asks for it first) and the report's modules with matplotlib (each scene's plots, once
    its views are scored, and the outputs)."""
    from ..gpu import open_ahead
    from ..util.imports import ImportAhead

    open_ahead(adapter)
    ImportAhead("matplotlib.figure", "matplotlib.style", "r360gpu.report.outputs")


def bundles_from_args(args) -> list:
    """The scenes the command line names: plain bundles, METHOD=FOLDER groups, and a --benchmark root."""
    from dataclasses import replace

    from ..bundle import group_pairs, load_benchmark, load_bundle, parse_method_folders
    from ..errors import InputError

    plain, pairs = parse_method_folders(args.bundles)
    if not plain and not pairs and not args.benchmark:
        raise InputError("nothing to score: give BUNDLE folders, METHOD=FOLDER pairs or --benchmark ROOT")
    if args.scene_name and not pairs and len(plain) != 1:
        raise InputError("--scene-name names the scene of METHOD=FOLDER folders, or of one bundle")
    if args.scene_name is not None:
        from ..bundle.names import bad_name

        reason = bad_name(args.scene_name)
        if reason:
            raise InputError(f"--scene-name {args.scene_name!r} {reason} (it names output folders)")
    if getattr(args, "frame", None) is not None and (pairs or args.benchmark):
        raise InputError("--frame applies to BUNDLE folders with splat scenes, not to METHOD=FOLDER folders or "
                         "--benchmark roots (set frame in their scene.toml)")
    # --views selects a folder's views where it is loaded, checked as `check --views` does; the other
    # scenes (METHOD=FOLDER groups, --benchmark) are narrowed by evaluate() (bundle.views.narrow_views)
    views = list(args.views) if args.views else None
    bundles = [load_bundle(p, views=views, prompt=args.prompt, method_name=args.method_name,
                           frame=getattr(args, "frame", None)) for p in plain]
    if args.scene_name and not pairs:
        bundles = [replace(bundles[0], name=args.scene_name)]
    bundles += group_pairs(pairs, scene_name=args.scene_name, prompt=args.prompt)
    if args.benchmark:
        found, notes = load_benchmark(args.benchmark, prompt=args.prompt)
        for note in notes:
            print(f"note: {note}")
        bundles += found
    return bundles


def run(args) -> int:
    start_ahead(args.adapter)
    from ..util.outdir import check_output_folder

    from ..util.warning_log import collecting

    out = check_output_folder(args.out)  # before any work
    options_from_args(args)  # every option checked before any work (EvaluateOptions._check)
    check_probe_device(args)
    executor = executor_from_args(args)  # says how to install Ray before any work starts
    with collecting():  # the warnings of loading the bundles are the run's too (results.json)
        return score_and_report(bundles_from_args(args), out, args, executor)
