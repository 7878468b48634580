"""One form for list-valued flags in every sub-command: a repeatable flag that also takes comma lists.

``--views A --views B`` and ``--views A,B`` give ``["A", "B"]``.  A flag with
``nargs="+"`` would swallow the positional arguments after it
(``score --views P BUNDLE`` took BUNDLE as a pattern), so none is used.
"""
from __future__ import annotations

import argparse


class ListAction(argparse.Action):
    """Appends the comma-separated items of each occurrence (empty items are dropped)."""

    def __init__(self, option_strings, dest, item_type=str, **kwargs):
        self.item_type = item_type
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        items = list(getattr(namespace, self.dest, None) or [])
        if not str(values).replace(",", "").strip():  # --views '' would select nothing, or (dropped) everything
            parser.error(f"{option_string}: empty value {values!r}; give at least one item")
        for part in str(values).split(","):
            part = part.strip()
            if not part:
                continue
            try:
                items.append(self.item_type(part))
            except ValueError:
                parser.error(f"{option_string}: invalid value {part!r}")
        setattr(namespace, self.dest, items)


def add_views_option(p, *, help_tail: str = "") -> None:
    p.add_argument("--views", action=ListAction, metavar="PATTERN", default=None,
                   help="glob pattern selecting evaluation views by name (* ? [seq], case-sensitive); repeat the "
                        "flag or give a comma list (--views 'frame_0*' --views frame_120 or "
                        "--views 'frame_0*,frame_120')" + help_tail)
