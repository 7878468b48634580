"""``r360gpu check``: validate scene bundles and list every problem, without evaluating anything.

For each bundle, prints one line per problem (``FILE: problem``) and a
summary line; then a total.  Exit code 0 when every bundle is valid, 2
otherwise (bad input, as for every r360gpu command).
"""
from __future__ import annotations

import argparse

from ..bundle import DEFAULT_METHOD_NAME, PROMPT_FILE, Bundle, Problem, inspect_bundle
from .frame_option import add_frame_option
from .lists import add_views_option


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``check`` sub-command to ``subparsers``; returns its parser."""
    p = subparsers.add_parser(
        "check",
        help="validate scene bundles and list every problem",
        description=(
            "Validate scene bundles (folders with scene.toml, or public Remove360 evaluation folders) and "
            "list every problem found: missing or unknown keys, missing or unreadable files, views "
            "without a mask, camera or rendering, size mismatches, bad method names. Cameras, masks, "
            "splat files and renderings are read with the readers score uses, so OK means score accepts "
            "the inputs."
        ),
    )
    p.add_argument("bundles", nargs="+", metavar="BUNDLE", help="bundle folder (or its scene.toml)")
    add_views_option(p, help_tail="; replaces the bundle's 'views'")
    p.add_argument("--prompt", default=None,
                   help=f"category prompt (replaces the bundle's; Remove360 folders: instead of {PROMPT_FILE})")
    p.add_argument("--method-name", default=None, metavar="NAME",
                   help=f"name of a Remove360 folder's method (default: {DEFAULT_METHOD_NAME!r})")
    add_frame_option(p)
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Execute ``r360gpu check``; returns 0 when every bundle is valid, else 2."""
    from ..util.warning_log import collecting

    with collecting():  # doubtful inputs (e.g. a mask read from its alpha) are printed as one line each
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    n_bad = n_problems = 0
    for path in args.bundles:
        bundle, problems = inspect_bundle(path, views=args.views, prompt=args.prompt,
                                          method_name=args.method_name, frame=args.frame, deep=True)
        if bundle is not None and bundle.target is not None:
            problems = target_problems(bundle)
        for problem in problems:
            print(problem)
        if problems:
            n_bad += 1
            n_problems += len(problems)
            print(f"{path}: INVALID ({len(problems)} problem{'s' if len(problems) != 1 else ''})")
        else:
            print(f"{path}: OK ({summary(bundle)})")
    n = len(args.bundles)
    if n > 1:
        print(f"{n} bundles checked: {n - n_bad} valid, {n_bad} invalid"
              + (f" ({n_problems} problems)" if n_problems else ""))
    return 0 if n_bad == 0 else 2


def target_problems(bundle: Bundle) -> list[Problem]:
    """The problem (none or one) of a valid bundle's ``[target]``, found by the validation ``score``
    runs (:func:`r360gpu.lift.resolve.check_target`: indices, box, given masks, the lift itself)."""
    from ..errors import InputError
    from ..lift.resolve import check_target
    from ..util import warning_log

    try:
        with warning_log.where(scene=bundle.name):
            check_target(bundle, warn=warning_log.warn)
    except InputError as e:
        return [Problem(e.path, f"{e.problem} ([target])")]
    return []


def summary(bundle: Bundle) -> str:
    """One line describing a valid bundle: scene, layout, views, sources."""
    def kind(spec) -> str:
        return "splat" if spec.kind == "scene" else "renders"

    methods = ", ".join(f"{name} ({kind(s)}{', own pre' if name in bundle.method_pres else ''})"
                        for name, s in bundle.methods.items())
    n_cams = "" if bundle.cameras is None else f", cameras from {bundle.cameras_path}"
    ref = f"reference ({kind(bundle.reference)})" if bundle.reference is not None else "no reference"
    return (f"scene {bundle.name!r} [{bundle.layout}], prompt {bundle.prompt!r}, {len(bundle.views)} view"
            f"{'s' if len(bundle.views) != 1 else ''}{n_cams}; pre ({kind(bundle.pre)}), {ref}; "
            f"methods: {methods}")
