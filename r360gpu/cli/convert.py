"""``r360gpu convert``: a splat bundle written in the layouts trainers and the public evaluation code leave."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "convert",
        help="write a bundle as an INRIA output folder, a gsplat output, a nerfstudio export and public "
             "Remove360 folders",
        description="Write a scene.toml bundle whose sources are splat files in its cameras' frame in other "
                    "layouts (see docs/your-scene.md): OUT/inria/NAME, OUT/gsplat/NAME (gsplat's normalised "
                    "world), OUT/nerfstudio/NAME (a dataparser frame) and OUT/public/METHOD/NAME_PROMPT. "
                    "Each scores as the bundle does.",
    )
    p.add_argument("bundles", nargs="+", metavar="BUNDLE", help="bundle folders (or their scene.toml)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--layouts", default=None, metavar="LIST",
                   help="comma-separated layouts to write, of inria, gsplat, nerfstudio, public (default: all)")
    p.add_argument("--adapter", default=None,
                   help="GPU adapter of the public layout's renders: auto, gpu, gpu:N, cpu, or part of its name")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..gpu import get_context
    from ..synthetic.layouts import LAYOUTS, write_layouts
    from ..util.outdir import check_output_folder

    out = check_output_folder(args.out)
    layouts = LAYOUTS if args.layouts is None else [x.strip() for x in args.layouts.split(",") if x.strip()]
    ctx = get_context(args.adapter) if "public" in layouts else None
    for bundle in args.bundles:
        for layout, folders in write_layouts(bundle, out, layouts=layouts, ctx=ctx).items():
            for folder in folders:
                print(f"{bundle} -> {folder} ({layout})")
    return 0
