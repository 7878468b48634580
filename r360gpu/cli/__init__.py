"""The ``r360gpu`` command line.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
taking the parsed ``argparse.Namespace`` and returning an exit code.

Exit codes: 0 success; 1 a check failed (e.g. ``doctor`` found a mismatch);
2 bad input or usage (one-line reason on stderr; traceback only with
``--debug``), including an output that cannot be written (read-only file
system, disk full); 3 no usable GPU adapter; 130 interrupted (Ctrl-C, at
any moment: even during the first imports, no traceback is shown).
"""
from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from ..errors import GpuUnavailableError, R360Error

# Order is the order shown in --help.
_COMMANDS = ["demo", "score", "check", "inpaint", "view", "tables", "convert", "doctor"]


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


def entry() -> int:
    """The `r360gpu` command: `main` with Ctrl-C kept out of imports (`r360gpu.util.interrupts`), which
    a library call of `main` leaves to its caller."""
    from ..util.interrupts import install

    install()
    return main()


def main(argv: list[str] | None = None) -> int:
    # Everything, the heavy imports of build_parser() included, runs under the Ctrl-C handler.
    args = None
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):  # bare `r360gpu`: the help is the answer
            parser.print_help()
            return 0
        return _run(args)
    except KeyboardInterrupt:
        print("r360gpu: interrupted" + _resume_hint(args), file=sys.stderr)
        return 130
    except Exception as e:
        # Ctrl-C inside a C extension's import (matplotlib's _image, say) comes out as
        # "ImportError: initialization failed" caused by the KeyboardInterrupt: still an interrupt.
        if not _caused_by_interrupt(e):
            raise
        print("r360gpu: interrupted" + _resume_hint(args), file=sys.stderr)
        return 130


def _caused_by_interrupt(e: BaseException) -> bool:
    """True when a KeyboardInterrupt is in the cause/context chain of ``e``."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def _resume_hint(args) -> str:
    if args is None or getattr(args, "command", None) not in ("score", "demo"):
        return ""
    return ("; run the same command again to resume (finished views are kept in the output folder's "
            ".r360cache; --force starts over)")


def _run(args) -> int:
    try:
        return int(args.func(args) or 0)
    except GpuUnavailableError as e:
        if args.debug:
            traceback.print_exc()
        print(f"r360gpu: error: {e}", file=sys.stderr)
        return 3
    except (R360Error, OSError) as e:
        # OSError: a file that vanished or cannot be read or written (read-only file system, disk
        # full) is the user's environment, not a bug: one line naming the file.
        if args.debug:
            traceback.print_exc()
        print(f"r360gpu: error: {_one_line(e)}", file=sys.stderr)
        return 2


def _one_line(e: BaseException) -> str:
    if isinstance(e, OSError) and not isinstance(e, R360Error) and e.filename is not None:
        return f"{e.filename}: {e.strerror or e}"
    return str(e)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
