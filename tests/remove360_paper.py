"""Loaders for the Remove360 paper tables transcribed under tests/data/.

Each CSV there starts with '#' comment lines naming the paper table it comes
from.  Values are kept with their printed precision so tests can compare "to
the printed precision".
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

DATA = Path(__file__).parent / "data"
AXES_CSV = DATA / "remove360_paper_axes.csv"
METHODS = ("GC", "AF", "AF+i", "3DGIC", "3DGIC+i", "OC")


@dataclass(frozen=True)
class Printed:
    """A number as printed in the paper: its value and number of decimals."""

    value: float
    decimals: int

    @property
    def half_ulp(self) -> float:
        """Half a unit in the last printed place: the rounding error of the print."""
        return 0.5 * 10.0 ** -self.decimals

    def matches(self, x: float) -> bool:
        """True when ``x`` prints as this value (rounding half away, with 1e-9 slack)."""
        return abs(x - self.value) <= self.half_ulp + 1e-9


def _printed(text: str) -> Printed | None:
    text = text.strip()
    if not text:
        return None
    decimals = len(text.split(".")[1]) if "." in text else 0
    return Printed(float(text), decimals)


def load(name: str) -> list[dict]:
    """Rows of tests/data/<name> with string keys and Printed (or None) numbers.

    The first column(s) named scene/method/pair stay strings.
    """
    with open(DATA / name, encoding="utf-8") as f:
        lines = [line for line in f if line.strip() and not line.startswith("#")]
    rows = []
    for row in csv.DictReader(lines):
        rows.append({k: (v if k in ("scene", "method", "pair") else _printed(v)) for k, v in row.items()})
    return rows


def by_method(name: str) -> dict[str, dict]:
    return {row["method"]: row for row in load(name)}
