"""``r360gpu inpaint``: the inpainting-quality benchmarks (360-USID / AuraFusion360, SPIn-NeRF) on their folders.

``inpaint 360usid DATA METHOD=FOLDER ... --out DIR`` and ``inpaint spinnerf ...`` score renders
made elsewhere against the benchmark's photographs (PSNR, SSIM, masked PSNR, masked SSIM as the
benchmark defines them, `r360gpu.metrics.inpainting`; LPIPS, masked LPIPS, FID and KID with
``--lpips-model``, ``--lpips-spatial-model`` and ``--inception-model`` ONNX exports); ``--compat``
gives the script's own numbers.  ``inpaint example DIR`` writes a small folder in each layout to try it on.  Outputs:
``results.json`` (`r360gpu.pipeline.inpaint`), ``results.csv`` (one row per view),
``tables.md``, ``tables.tex`` and ``report.html``, written together once every view is scored.
"""
from __future__ import annotations

import argparse
import sys

from ..io.inpaint_folders import SPINNERF_N_TEST
from .tables import _positive_int


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", metavar="DATA", help="a scene folder, or a folder of scene folders")
    p.add_argument("methods", metavar="METHOD=FOLDER", nargs="+",
                   help="a method's output folder; {scene} in FOLDER stands for the scene's name (with several "
                        "scenes and no {scene}, FOLDER/SCENE)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--masks", metavar="FOLDER", help="object masks used for every method ({scene} allowed)")
    p.add_argument("--compat", action="store_true",
                   help="the benchmark script's numbers exactly (its mask weights, NaN / inf kept in the means)")
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
    ex.set_defaults(func=run_example)


def run_example(args) -> int:
    from ..synthetic.inpaint_folders import write_inpaint_example

    paths = write_inpaint_example(args.out, n_scenes=args.n_scenes, n_views=args.n_views, width=args.width,
                                  height=args.height, seed=args.seed)
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
    inputs = {"data": args.data, "methods": dict(m.partition("=")[::2] for m in args.methods), "masks": args.masks}
    with collecting() as log:
        if args.protocol == "360usid":
            scenes = usid_scenes(args.data, args.methods, masks=args.masks)
        else:
            scenes = spinnerf_scenes(args.data, args.methods, masks=args.masks, factor=args.factor,
                                     n_test=args.n_test)
            inputs.update(factor=args.factor, n_test=args.n_test)
        models = _models(args, scenes[0].photos[0])
        inputs["models"] = _describe(models)
        run_ = score_scenes(scenes, protocol=args.protocol, mode=mode, show_progress=not args.quiet, **models)
        records = log.records()
    name = PROTOCOLS[args.protocol]
    for scene in scenes:
        print(f"Scene:  {scene.name}")
        for r in run_.results:
            if r.scene == scene.name:
                print("\n".join(tables.script_lines(r)))
        print("====================================")
    doc = results_document(run_, inputs, records)
    tabs = tables.tables(run_.results, run_.methods, name, mode)
    notes = doc["differs_from_script"] or [doc["mode_note"]]
    files = {n: out / n for n in ("results.json", "results.csv", "tables.md", "tables.tex", "report.html")}
    with open_output_folder(out), all_or_nothing(files.values()):
        write_json(files["results.json"], doc, indent=1, allow_nan=False)
        write_text(files["results.csv"], tables.csv_text(run_.results))
        write_text(files["tables.md"], tables.markdown(tabs))
        write_text(files["tables.tex"], tables.latex(tabs))
        write_text(files["report.html"], tables.html_page(tabs, f"{name}: inpainting quality", notes,
                                                          [format_record(r) for r in records]))
    sys.stdout.write(tables.markdown(tabs[:1]))
    print(f"{sum(len(s.photos) for s in scenes)} views x {len(run_.methods)} method(s) in {run_.seconds:.1f} s; "
          f"wrote {out / 'report.html'}, results.json, results.csv, tables.md, tables.tex")
    return 0
