"""``r360gpu view BUNDLE [--results PATH]``: the interactive viewer (needs the ``viewer`` extra).

The viewer lives in the ``r360gpu.viewer`` package and is imported only
when the command runs, so r360gpu works without its optional dependencies
(glfw, imgui-bundle, rendercanvas).
"""
from __future__ import annotations

import importlib.util

from ..errors import R360Error

#: Modules of the ``viewer`` extra.
VIEWER_MODULES = ("glfw", "imgui_bundle", "rendercanvas")
INSTALL_HINT = "pip install -e '.[viewer]' (from a checkout)"


class ViewerUnavailableError(R360Error):
    """The viewer's optional dependencies are not installed."""


def missing_modules() -> list[str]:
    """The viewer's modules that cannot be imported here."""
    return [m for m in VIEWER_MODULES if importlib.util.find_spec(m) is None]


def _add_arguments(p) -> None:
    # The same options as ``python -m r360gpu.viewer``; defined here too so that
    # ``r360gpu view --help`` works without the extra installed.
    try:
        from r360gpu.viewer.launch import add_arguments
    except ImportError:
        add_arguments = None
    if add_arguments is not None:
        add_arguments(p)
    else:
        p.add_argument("bundle", help="scene bundle folder")
        p.add_argument("--results", metavar="PATH", default=None, help="results.json of 'r360gpu score'")
    p.add_argument("--prompt", default=None,
                   help="category prompt (replaces the bundle's; Remove360 folders: instead of prompt.txt)")
    p.add_argument("--method-name", default=None, metavar="NAME",
                   help="name of a Remove360 folder's method (default: 'after')")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "view", help="interactive viewer of a bundle (needs the viewer extra)",
        description="Open a window on a scene bundle: pre / reference / methods, side by side or wiped, with "
                    "depth, |dD| and changed-mask overlays and the per-view axes of a results.json. "
                    f"Needs the viewer extra: {INSTALL_HINT}.")
    _add_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    missing = missing_modules()
    if missing:
        raise ViewerUnavailableError(
            f"the viewer needs {', '.join(missing)}, which {'is' if len(missing) == 1 else 'are'} not installed; "
            f"install the viewer extra: {INSTALL_HINT}")
    try:
        from r360gpu.viewer.launch import run as launch
    except ImportError as e:
        raise ViewerUnavailableError(f"cannot import the viewer package ({e}); install r360gpu with the viewer "
                                     f"extra: {INSTALL_HINT}") from None
    if args.prompt is not None or args.method_name is not None:
        # Loaded here with the overrides; the viewer takes a loaded Bundle as it is (load_bundle passes it on).
        from ..bundle import load_bundle

        args.bundle = load_bundle(args.bundle, prompt=args.prompt, method_name=args.method_name)
    return launch(args)
