"""What the README's and docs' sample commands write into a checkout is ignored by git: following the
docs leaves `git status` clean."""
from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from test_docs_samples import BLOCKS

ROOT = Path(__file__).resolve().parents[1]
#: Flags whose value is a folder the command writes into, and flags whose value is a file it writes.
DIR_FLAGS = {"--out", "-o"}
FILE_FLAGS = {"--json", "--output", ">", ">>"}


def _written() -> set[tuple[str, str]]:
    """(page, path) of every output the sh and python samples name; a folder as a file inside it."""
    out = set()
    for page, lang, _, body in BLOCKS:
        if lang == "sh":
            for line in body.replace("\\\n", " ").splitlines():
                toks = shlex.split(line, comments=True)
                for flag, value in zip(toks, toks[1:]):
                    if flag in DIR_FLAGS and value:
                        out.add((page, value.rstrip("/") + "/report.html"))
                    elif flag in FILE_FLAGS:
                        out.add((page, value))
                for tok in toks:
                    flag, eq, value = tok.partition("=")
                    if eq and flag in DIR_FLAGS | FILE_FLAGS and value:
                        out.add((page, value + ("/report.html" if flag in DIR_FLAGS else "")))
        elif lang == "python":
            out |= {(page, m + "/report.html") for m in re.findall(r"""\bout\s*=\s*["']([^"']+)["']""", body)}
    return out


def test_the_scan_finds_the_samples_outputs():
    """The scan sees the outputs it must (so the test below checks something)."""
    written = {p for _, p in _written()}
    assert {"room-scores/report.html", "paper.json", "out-mine/report.html"} <= written
    assert len(written) >= 10


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a git checkout")
def test_every_sample_output_is_ignored_by_git():
    paths = sorted(_written())
    proc = subprocess.run(["git", "check-ignore", "--no-index", "--stdin"], cwd=ROOT, capture_output=True,
                          text=True, input="\n".join(p for _, p in paths) + "\n", timeout=60)
    ignored = set(proc.stdout.split())
    missing = [(page, p) for page, p in paths if p not in ignored]
    assert missing == [], f"add to .gitignore (or write under an ignored folder): {missing}"
