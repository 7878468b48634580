"""docs/protocol.md lists every constant of r360gpu.protocol with the module's value."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import r360gpu.protocol as protocol

PAGE = Path(__file__).resolve().parents[1] / "docs" / "protocol.md"
ROW = re.compile(r"^\| `([A-Z_]+)` \| `([^`]+)` \| (.+) \|$")


def _table() -> dict:
    rows = [ROW.match(line) for line in PAGE.read_text(encoding="utf-8").splitlines()]
    return {m.group(1): ast.literal_eval(m.group(2)) for m in rows if m}


def test_every_constant_is_on_the_page_with_its_value():
    table = _table()
    assert sorted(table) == sorted(protocol.__all__)
    for name, value in table.items():
        got = getattr(protocol, name)
        assert value == got and type(value) is type(got), (name, value, got)


def test_the_definitions_name_only_real_constants():
    """Every constant-like name the page's prose uses in backticks is one of the module's."""
    text = PAGE.read_text(encoding="utf-8").split("## Constants")[0]
    named = set(re.findall(r"`([A-Z][A-Z_]{3,})`", text))
    assert named and named <= set(protocol.__all__), named - set(protocol.__all__)
