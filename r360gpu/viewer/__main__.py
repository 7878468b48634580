"""``python -m viewer BUNDLE [--results results.json]``: the interactive viewer in a window."""
from __future__ import annotations

import argparse
import sys

from .launch import add_arguments, run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m viewer", description="Interactive viewer of a scene bundle.")
    add_arguments(parser)
    args = parser.parse_args(argv)
    from r360gpu.errors import GpuUnavailableError, R360Error

    try:
        return run(args)
    except GpuUnavailableError as e:
        print(f"viewer: error: {e}", file=sys.stderr)
        return 3
    except (R360Error, FileNotFoundError) as e:
        print(f"viewer: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
