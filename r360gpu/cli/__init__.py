"""The ``r360gpu`` command line.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed ``argparse.Namespace`` and returning an exit code.

Exit codes: 0 success; 1 a check failed (e.g. ``doctor`` found a mismatch);
2 bad input or usage (one-line reason on stderr; traceback only with
``--debug``); 3 no usable GPU adapter.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from ..errors import GpuUnavailableError, R360Error

# Order is the order shown in --help.
_COMMANDS = ["demo", "score", "check", "view", "tables", "doctor"]


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="r360gpu",
        description="Evaluate object removal in 3D Gaussian Splatting scenes (Remove360 protocol).",
    )
    parser.add_argument("--version", action="version", version=f"r360gpu {__version__}")
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _COMMANDS:
        importlib.import_module(f".{name}", __name__).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):  # bare `r360gpu`: the help is the answer
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except GpuUnavailableError as e:
        if args.debug:
            traceback.print_exc()
        print(f"r360gpu: error: {e}", file=sys.stderr)
        return 3
    except (R360Error, FileNotFoundError, PermissionError) as e:
        if args.debug:
            traceback.print_exc()
        print(f"r360gpu: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("r360gpu: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
