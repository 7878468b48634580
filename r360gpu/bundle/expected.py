"""``[expected.METHOD]`` tables of scene.toml: what a method's known failure should do to the axes.

A benchmark whose failures are known (the synthetic demo: every simulated
method has one) states them in its bundle, so the report can say per method
which axis should catch the failure and whether it did, without knowing the
methods by name::

    [expected.floaters]
    failure = "part of the target left behind as semi-transparent residue"
    caught_by = ["s_sem", "s_geo", "s_str"]

``failure``: one sentence (required).  ``caught_by``: the axes (``s_sem``,
``s_geo``, ``s_str``) that should fall low; empty for a method without a
failure (every axis should stay high).  Each key must name a method of the
bundle.
"""
from __future__ import annotations

from ..protocol import AXES
KEYS = ("failure", "caught_by")


def parse_expected(table, methods, bad) -> dict[str, dict]:
    """The validated ``[expected]`` table as {method: {"failure": str, "caught_by": [axis, ...]}};
    every problem goes to ``bad(message)``."""
    out: dict[str, dict] = {}
    if not isinstance(table, dict):
        bad("'expected' must hold one table per method, e.g. [expected.mine] failure = \"...\"")
        return out
    for name, entry in table.items():
        where = f"[expected.{name}]"
        if name not in methods:
            bad(f"{where} names no method of the bundle (methods: {', '.join(methods) or 'none'})")
            continue
        if not isinstance(entry, dict):
            bad(f"{where} must be a table with 'failure' and 'caught_by'")
            continue
        unknown = [k for k in entry if k not in KEYS]
        if unknown:
            bad(f"unknown key '{unknown[0]}' in {where} (known keys: {', '.join(KEYS)})")
        failure = entry.get("failure")
        if not isinstance(failure, str) or not failure.strip():
            bad(f"{where}: 'failure' must be a non-empty string describing the failure")
            continue
        axes = entry.get("caught_by", [])
        if not isinstance(axes, list) or any(a not in AXES for a in axes):
            bad(f"{where}: 'caught_by' must be a list of axes from {', '.join(AXES)}, got {axes!r}")
            continue
        out[name] = {"failure": failure.strip(), "caught_by": [a for a in AXES if a in axes]}
    return out
