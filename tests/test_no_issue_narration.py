"""Docstrings, comments and pages say what the code or the test does, not which tracker entry asked.

Scanned: the docstrings and comments of every test module (their string literals are test data), the
whole text of every module of ``r360gpu/`` and ``bench/`` (help strings and printed goals included),
the comments of ``shaders/*.wgsl``, and README.md and ``docs/*.md``.  A web address is left out before
matching, so a link to another project's tracker entry stays allowed.
"""
from __future__ import annotations

import functools
import re

import pytest

from test_doc_paths import ROOT, prose, repository_files

#: The word for a tracker entry followed by its number (an optional "#" between), or its possessive after "the".
NARRATION = re.compile(r"\bissues?\s+#?\d+|\bthe issue's\b", re.I)
URL = re.compile(r"\b[a-z][a-z0-9+.-]*://\S+", re.I)


def narrations(text: str) -> list[str]:
    """The tracker references in ``text``, web addresses left out."""
    return [m.group(0) for m in NARRATION.finditer(URL.sub(" ", text))]


@functools.cache
def scanned_texts() -> tuple:
    """(file:line, text) of everything the module docstring lists."""
    return tuple(_scan())


def _scan():
    for rel in repository_files():
        top = rel.split("/")[0]
        path = ROOT / rel
        if rel.endswith(".py") and top == "tests":
            for line, text in prose(path.read_text(encoding="utf-8")):
                yield f"{rel}:{line}", text
        elif rel.endswith(".py") and top in ("r360gpu", "bench"):
            yield from _lines(rel, path.read_text(encoding="utf-8").splitlines())
        elif rel.endswith(".wgsl") and top == "shaders":
            lines = path.read_text(encoding="utf-8").splitlines()
            yield from _lines(rel, [line.partition("//")[2] for line in lines])
        elif rel.endswith(".md") and (rel == "README.md" or (top == "docs" and rel.count("/") == 1)):
            yield from _lines(rel, path.read_text(encoding="utf-8").splitlines())


def _lines(rel, lines):
    for number, line in enumerate(lines, 1):
        yield f"{rel}:{number}", line


def test_no_docstring_comment_or_page_narrates_a_tracker_entry():
    found = [f"{where}: {hit!r}" for where, text in scanned_texts() for hit in narrations(text)]
    assert not found, ("say what the code or the test checks, not which issue asked (the history is in git):\n"
                       + "\n".join(found))


def test_the_scan_covers_every_kind_of_file():
    kinds = {where.split(":")[0].rsplit(".", 1)[-1] for where, _ in scanned_texts()}
    places = {where.split("/")[0] for where, _ in scanned_texts()}
    assert {"py", "wgsl", "md"} <= kinds and {"tests", "r360gpu", "bench", "shaders", "docs"} <= places


@pytest.mark.parametrize("text, expect", [
    ("(issue 26, class 2).", ["issue 26"]),
    ("against the goals of Issue 27's run", ["Issue 27"]),
    ("see issues #3 and 4", ["issues #3"]),
    ("scaled down from the issue's case", ["the issue's"]),
    ("peer bug: https://github.com/pmneila/PyMCubes/issues/12 (fixed upstream)", []),
    ("an issue with 3 views; issues were none; notes/issue6_design.md", []),
])
def test_narration_tokens(text, expect):
    assert narrations(text) == expect
