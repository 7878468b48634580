"""``r360gpu tables``: aggregate per-(scene, method) axes into the Remove360 tables.

Reads a CSV with columns ``scene, method, s_sem, s_geo, s_str`` (optional
``n_views`` for view-weighted pooling, optional ``iou_drop``), prints every
aggregate table (per-scene RQS, overall, scene-macro means, rank aggregation,
reliability, axis association) as Markdown or LaTeX, and optionally writes the
numbers as JSON (see :func:`r360gpu.aggregate.aggregate_tables`).

Without ``n_views`` (and with several scenes) the Overall row is the scene-macro mean, and a note says
that the paper's Overall row (tab:main_results) is view-weighted, so it cannot
be rebuilt from per-scene axes alone (tests/test_aggregate_rqs.py shows it
differs from the scene-macro mean of the paper's per-scene axes).
"""
from __future__ import annotations

import argparse
import sys

from ..aggregate import aggregate_tables, read_axes_csv
from ..errors import InputError
from ..protocol import N_BOOT, N_PERM
from ..report.tables import FORMATS, render_tables
from ..util.atomic import write_json


OVERALL_NOTE = (
    "no n_views column, so the Overall row is the unweighted mean over scenes (scene-macro). The paper's "
    "Overall row (tab:main_results) is view-weighted, pooled over all views of all scenes; it cannot be rebuilt "
    "from per-scene axes without the per-scene view counts, which the paper does not publish, so it differs "
    "from this row (e.g. GC acc_seg: 0.875 printed, 0.886 scene-macro). Add an n_views column to pool by views.")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return value


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must not be negative")
    return value


def register(subparsers) -> argparse.ArgumentParser:
    """Add the ``tables`` sub-command to ``subparsers``; returns its parser."""
    p = subparsers.add_parser(
        "tables",
        help="aggregate per-scene axes into RQS, ranks, reliability and axis-association tables",
        description=(
            "Aggregate per-(scene, method) axis values into the Remove360 tables. AXES.csv has columns "
            "scene, method, s_sem, s_geo, s_str (values in [0, 1]) and optionally n_views (positive "
            "integer; enables view-weighted pooling of the Overall row) and iou_drop (diagnostic). "
            "Lines starting with '#' are comments."
        ),
    )
    p.add_argument("axes_csv", metavar="AXES.csv", help="per-(scene, method) axes")
    p.add_argument("--json", metavar="OUT", help="also write the numbers to this JSON file (atomically)")
    p.add_argument("--format", choices=FORMATS, default="md", help="table format printed (default: md)")
    p.add_argument("--n-boot", type=_positive_int, default=N_BOOT, metavar="N",
                   help="bootstrap resamples for P(beats best) (default: %(default)s)")
    p.add_argument("--n-perm", type=_positive_int, default=N_PERM, metavar="N",
                   help="within-scene permutations for the scene-centred rho p-value (default: %(default)s)")
    p.add_argument("--seed", type=_non_negative_int, default=0,
                   help="seed of the bootstrap and permutation generators (default: 0)")
    p.add_argument("--rank-decimals", type=_non_negative_int, default=None, metavar="D",
                   help="round the overall axes to D decimals before ranking (default: full precision)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    """Execute ``r360gpu tables``; returns the exit code (0).

    Raises:
        InputError: a bad CSV (the CLI prints it as a one-line message, exit 2).
    """
    cells = read_axes_csv(args.axes_csv)
    result = aggregate_tables(cells, n_boot=args.n_boot, n_perm=args.n_perm, seed=args.seed,
                              rank_decimals=args.rank_decimals)
    if cells.n_views is None and len(cells.scenes) > 1:  # one scene: Overall is that scene either way
        result.setdefault("notes", {})["overall_pooling"] = OVERALL_NOTE
    if args.json:
        try:
            write_json(args.json, result, allow_nan=False)
        except OSError as e:
            raise InputError(f"cannot write JSON: {e.strerror or e}", args.json) from None
    # Notes on omitted tables (fewer than two scenes) are part of this text.
    sys.stdout.write(render_tables(result, args.format))
    return 0
