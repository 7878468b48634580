"""``r360gpu inpaint``: the inpainting-quality benchmarks (360-USID / AuraFusion360, SPIn-NeRF) on their folders.

``inpaint 360usid DATA METHOD=FOLDER ... --out DIR`` and ``inpaint spinnerf ...`` score renders
made elsewhere (or splat scenes, rendered here at the test cameras) against the benchmark's
photographs (PSNR, SSIM, masked PSNR, masked SSIM as the benchmark defines them,
`r360gpu.metrics.inpainting`; LPIPS, masked LPIPS, FID and KID with ``--lpips-model``,
``--lpips-spatial-model`` and ``--inception-model`` ONNX exports); ``--compat`` gives the script's
own numbers.  ``--pre`` with ``--target`` gives masks (the lifted target's) to methods without any;
``--orbit N`` with ``--reference`` also scores the splat methods at orbit poses against the
reference reconstruction (`r360gpu.pipeline.inpaint_orbit`).  ``inpaint example DIR`` writes a
small folder in each layout to try it on.  Outputs: ``results.json`` (`r360gpu.pipeline.inpaint`),
``results.csv`` (one row per view), ``tables.md``, ``tables.tex`` and ``report.html``, written
together once every view is scored.
"""
from __future__ import annotations

import argparse
import sys

from ..io.inpaint_folders import SPINNERF_N_TEST
from .frame_option import add_frame_option
from .tables import _positive_int


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", metavar="DATA", help="a scene folder, or a folder of scene folders")
    p.add_argument("methods", metavar="METHOD=FOLDER", nargs="+",
                   help="a method's output folder, or its splat scene (.ply, .splat, an INRIA output folder), "
                        "rendered here at the test cameras; {scene} in FOLDER stands for the scene's name (with "
                        "several scenes and no {scene}, FOLDER/SCENE)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--masks", metavar="FOLDER", help="object masks used for every method ({scene} allowed)")
    p.add_argument("--compat", action="store_true",
                   help="the benchmark script's numbers exactly (its mask weights, NaN / inf kept in the means)")
    p.add_argument("--cameras", metavar="PATH",
                   help="the test cameras of splat methods: a COLMAP model, cameras.json or transforms.json "
                        "naming the photographs ({scene} allowed; default: the scene's sparse/0)")
    add_frame_option(p)
    p.add_argument("--pre", metavar="SPLAT",
                   help="the reconstruction with the object ({scene} allowed): with --target, methods without "
                        "masks are scored on the target's masks rendered from it at the test cameras")
    p.add_argument("--target", metavar="TARGET",
                   help="the object on pre's Gaussians, as scene.toml's [target]: FILE.npy / FILE.ply (indices), "
                        "box:X0,Y0,Z0,X1,Y1,Z1, or masks:FOLDER (<image stem>.png masks of some cameras, lifted)")
    p.add_argument("--orbit", type=_positive_int, default=0, metavar="N",
                   help="also score the splat methods at N orbit poses around the target (as score --orbit) "
                        "against the renders of --reference, in a table of their own (needs --pre and --target)")
    p.add_argument("--reference", metavar="SPLAT",
                   help="the reconstruction of the scene without the object ({scene} allowed), for --orbit")
    g = p.add_argument_group("model metrics (ONNX exports, docs/models.md; without one its metrics are not computed)")
    g.add_argument("--lpips-model", metavar="ONNX", help="plain VGG LPIPS export (lpips.LPIPS(net='vgg')): LPIPS")
    g.add_argument("--lpips-spatial-model", metavar="ONNX",
                   help="spatial VGG LPIPS export (lpips.LPIPS(net='vgg', spatial=True)): masked LPIPS")
    g.add_argument("--inception-model", metavar="ONNX",
                   help="pytorch-fid Inception export: FID and KID per scene between photographs and renders")
    g.add_argument("--probe-device", default="auto", metavar="DEVICE", type=str.lower,
                   help="onnxruntime execution provider of those models: auto (default: a GPU provider the "
                        "installed onnxruntime has, else cpu), cpu, cuda, tensorrt, webgpu, directml, coreml")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def register(sub) -> None:
    p = sub.add_parser("inpaint", help="score inpainting quality as 360-USID (AuraFusion360) or SPIn-NeRF do",
                       description="Score a method's renders at the benchmark's test views against its photographs "
                                   "of the scene without the object: PSNR, SSIM and LPIPS over the whole image and "
                                   "inside the object mask, and FID/KID, "
                                   "as the benchmark's evaluation defines them (docs/your-scene.md).")
    kinds = p.add_subparsers(dest="protocol", metavar="BENCHMARK", required=True)
    usid = kinds.add_parser("360usid", help="360-USID folders (AuraFusion360's scripts/aura_eval.py)",
                            description="DATA/SCENE/test_images/*jpg are the photographs; FOLDER/renders/*png the "
                                        "method's renders and FOLDER/object_mask/*.png its masks, paired by natural "
                                        "sort order as the script pairs them.")
    _common(usid)
    spin = kinds.add_parser("spinnerf", help="SPIn-NeRF folders (first 40 photographs of images/ are the test views)",
                            description="DATA/SCENE/images/ (images_N/ with --factor N) holds the photographs; the "
                                        "first --n-test in natural order are the test views, taken without the "
                                        "object; masks are label/<stem>.png (test_label/ when present) beside them.")
    _common(spin)
    spin.add_argument("--factor", type=_positive_int, metavar="N", help="use images_N/ (downscaled N times)")
    spin.add_argument("--n-test", type=_positive_int, default=SPINNERF_N_TEST, metavar="N",
                      help="how many of the sorted photographs are test views (default %(default)s)")
    ex = kinds.add_parser("example", help="write a small generated folder in each layout",
                          description="Write DIR/360usid and DIR/spinnerf: procedural photographs, object masks and "
                                      "the renders of two simulated methods (blur, flat).")
    ex.add_argument("out", metavar="DIR")
    ex.add_argument("--n-scenes", type=_positive_int, default=2, metavar="N", help="scenes (default 2, at most 7)")
    ex.add_argument("--n-views", type=_positive_int, default=6, metavar="N", help="test views per scene (default 6)")
    ex.add_argument("--width", type=_positive_int, default=160, help="image width (default 160)")
    ex.add_argument("--height", type=_positive_int, default=120, help="image height (default 120)")
    ex.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    ex.add_argument("--splats", action="store_true",
                    help="also write DIR/360usid_splats: a demo scene in 360-USID's layout (COLMAP sparse/0, "
                         "test_images rendered from the reference) with its methods as splat files (.ply)")
    ex.set_defaults(func=run_example)


def run_example(args) -> int:
    from ..synthetic.inpaint_folders import write_inpaint_example

    paths = write_inpaint_example(args.out, n_scenes=args.n_scenes, n_views=args.n_views, width=args.width,
                                  height=args.height, seed=args.seed)
    if args.splats:
        from ..synthetic.inpaint_splats import write_usid_splat_example

        paths["360usid_splats"] = write_usid_splat_example(paths["360usid"].parent / "360usid_splats", seed=args.seed)
    for name, path in paths.items():
        print(f"{name}: {path}")
    return 0


def _models(args, photo) -> dict:
    """The model exports given, opened and checked on images of the size of ``photo`` (a photograph's
    path): an unloadable file or the wrong kind of export is an InputError naming it, before any view
    is scored."""
    given = {k: getattr(args, k) for k in ("lpips_model", "lpips_spatial_model", "inception_model")}
    if not any(given.values()):
        return {}
    from ..io.inpaint_folders import read_image
    from ..metrics.fidelity import LpipsModel
    from ..probes.inception import InceptionModel
    from ..probes.providers import choose

    device = choose(args.probe_device)
    opened = {}
    if given["lpips_model"]:
        opened["lpips"] = LpipsModel(given["lpips_model"], device)
    if given["lpips_spatial_model"]:
        opened["lpips_spatial"] = LpipsModel(given["lpips_spatial_model"], device)
    if given["inception_model"]:
        opened["inception"] = InceptionModel(given["inception_model"], device)
    size = read_image(photo).shape[:2] if {"lpips", "lpips_spatial"} & opened.keys() else None
    for key, spatial in (("lpips", False), ("lpips_spatial", True)):
        if key in opened:
            opened[key].require(spatial, size)
    return opened


def _describe(models: dict) -> dict:
    """results.json ``inputs.models``: each model's file, sha256 and the provider that ran it."""
    names = {"lpips": "lpips_model", "lpips_spatial": "lpips_spatial_model", "inception": "inception_model"}
    return {names[k]: m.describe() for k, m in models.items()}


def run(args) -> int:
    from ..io.inpaint_folders import spinnerf_scenes, usid_scenes
    from ..pipeline.inpaint import PROTOCOLS, results_document, score_scenes
    from ..report import inpaint as tables
    from ..util.atomic import all_or_nothing, write_json, write_text
    from ..util.outdir import check_output_folder, open_output_folder
    from ..util.warning_log import collecting, format_record

    out = check_output_folder(args.out)
    mode = "compat" if args.compat else "default"
    inputs = {"data": args.data, "methods": dict(m.partition("=")[::2] for m in args.methods), "masks": args.masks,
              "cameras": args.cameras, "frame": args.frame, "pre": args.pre, "target": args.target,
              "orbit": args.orbit, "reference": args.reference}
    with collecting() as log:
        if args.protocol == "360usid":
            scenes = usid_scenes(args.data, args.methods, masks=args.masks, cameras=args.cameras,
                                 need_cameras=args.pre is not None)
        else:
            scenes = spinnerf_scenes(args.data, args.methods, masks=args.masks, factor=args.factor,
                                     n_test=args.n_test, cameras=args.cameras, need_cameras=args.pre is not None)
            inputs.update(factor=args.factor, n_test=args.n_test)
        models = _models(args, scenes[0].photos[0])
        inputs["models"] = _describe(models)
        run_ = score_scenes(scenes, protocol=args.protocol, mode=mode, show_progress=not args.quiet,
                            frame=args.frame, pre=args.pre, target=args.target, orbit=args.orbit,
                            reference=args.reference, models=models)
        records = log.records()
    name = PROTOCOLS[args.protocol]
    for scene in scenes:
        print(f"Scene:  {scene.name}")
        for r in run_.results:
            if r.scene == scene.name:
                print("\n".join(tables.script_lines(r)))
        print("====================================")
    doc = results_document(run_, inputs, records)
    orbit = None
    if run_.orbits:
        from ..pipeline.inpaint_orbit import AGAINST_REFERENCE

        orbit = tables.orbit_table([r for o in run_.orbits.values() for r in o.results],
                                   {s: o.info.get("kept", 0) for s, o in run_.orbits.items()}, AGAINST_REFERENCE)
    tabs = tables.tables(run_.results, run_.methods, name, mode, orbit)
    notes = (doc["differs_from_script"] or [doc["mode_note"]]) + [
        f"{s}: masked metrics of the methods without masks use the {r['note']} ({r['source']}: {r['gaussians']} of "
        f"{r['of']} Gaussians of {r['pre']})" for s, r in doc["lifted_targets"].items()]
    files = {n: out / n for n in ("results.json", "results.csv", "tables.md", "tables.tex", "report.html")}
    with open_output_folder(out), all_or_nothing(files.values()):
        write_json(files["results.json"], doc, indent=1, allow_nan=False)
        write_text(files["results.csv"], tables.csv_text(run_.results))
        write_text(files["tables.md"], tables.markdown(tabs))
        write_text(files["tables.tex"], tables.latex(tabs))
        write_text(files["report.html"], tables.html_page(tabs, f"{name}: inpainting quality", notes,
                                                          [format_record(r) for r in records]))
    sys.stdout.write(tables.markdown(tabs[:1] + ([orbit] if orbit is not None else [])))
    print(f"{sum(len(s.photos) for s in scenes)} views x {len(run_.methods)} method(s) in {run_.seconds:.1f} s; "
          f"wrote {out / 'report.html'}, results.json, results.csv, tables.md, tables.tex")
    return 0
