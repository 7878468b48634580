"""Every file of this repository that a docstring or comment names exists.

A path is a token with a ``/`` ending in ``.md``, ``.py`` or ``.wgsl`` (``r360gpu/report/tables.py``,
``gpu/uniforms.py``, ``../README.md``), or a document in capitals such as ``README.md``.  It exists
when a file of the repository is that path, ends with it (paths are often written from a package
down), or is it taken from the naming file's own folder.  Files of other projects that the code
cites (the public Remove360 scripts, segment-anything, gsplat) are listed in :data:`ELSEWHERE`;
placeholders in capitals (``OUT/tables.md``) are left alone.
"""
from __future__ import annotations

import ast
import io
import os
import re
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCANNED = ("r360gpu", "tests", "bench")

PATH = re.compile(r"(?<![\w./:-])((?:[\w.-]+/)+[\w.-]+\.(?:md|py|wgsl)|[A-Z][A-Z_]+\.md)(?![\w/])")
#: Files of other repositories that docstrings cite, by project.
ELSEWHERE = {
    # the public Remove360 evaluation code (github.com/simonakocour/anything_left)
    "scripts/run_pipeline.py", "scripts/download_dataset.py", "scripts/compute_depth_diff.py",
    "scripts/evaluate_sam.py", "scripts/convert_gsam2_to_masks.py", "scripts/run_sam_on_rgb.py",
    "remove360/preprocessing/depth_diff.py", "remove360/evaluation/semantic.py", "remove360/evaluation/sam.py",
    "remove360/utils/io.py",
    # segment-anything
    "scripts/amg.py", "utils/amg.py",
    # AuraFusion360's evaluation (github.com/superlearnerG/my-AuraFusion360)
    "scripts/aura_eval.py", "utils/image_utils.py", "utils/loss_utils.py",
    # gsplat
    "examples/datasets/normalize.py", "examples/datasets/colmap.py",
    # what bench/public_peer/torch_standin.py lays out in a scratch folder at run time
    "torch/__init__.py", "torch/nn/functional.py",
    # the throwaway package tests/test_code_id.py builds
    "sub/b.py", "shaders/k.wgsl",
}


def repository_files() -> list[str]:
    """Every file under the root (relative, ``/``-separated), hidden folders (.git, .venv) and
    caches left out."""
    out = []
    for folder, dirs, names in os.walk(ROOT):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d not in ("__pycache__", "site")]
        rel = Path(folder).relative_to(ROOT)
        out += [(rel / n).as_posix() for n in names]
    return out


def prose(source: str):
    """(line, text) of every docstring (a string alone as a statement) and comment of ``source``."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            yield node.lineno, node.value.value
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            yield tok.start[0], tok.string


def named_paths(text: str) -> list[str]:
    """The repository paths ``text`` names (placeholders such as ``OUT/x.md`` left out)."""
    return [p for p in PATH.findall(text)
            if not any(re.fullmatch(r"[A-Z][A-Z0-9_]*", part) for part in p.split("/")[:-1])]


def exists(path: str, where: str, files: list[str]) -> bool:
    """Whether ``path``, named in file ``where`` (relative to the root), is a file of the repository."""
    if path in ELSEWHERE:
        return True
    local = os.path.normpath(os.path.join(os.path.dirname(where), path))
    return any(f == path or f.endswith("/" + path) or f == local for f in files)


def dangling(files: list[str]) -> list[str]:
    out = []
    for rel in files:
        if not (rel.endswith(".py") and rel.split("/")[0] in SCANNED):
            continue
        for line, text in prose((ROOT / rel).read_text(encoding="utf-8")):
            out += [f"{rel}:{line}: {p}" for p in named_paths(text) if not exists(p, rel, files)]
    return sorted(set(out))


def test_every_path_a_docstring_or_comment_names_exists():
    bad = dangling(repository_files())
    assert not bad, ("docstrings or comments name files that are not in the repository "
                     "(point at the file that is, or list another project's file in ELSEWHERE):\n" + "\n".join(bad))


@pytest.mark.parametrize("text, expect", [
    ("structure in ``notes/issue6_design.md``; schema", ["notes/issue6_design.md"]),
    ("see r360gpu/gpu/uniforms.py and shaders/lift_accumulate.wgsl.", ["r360gpu/gpu/uniforms.py",
                                                                     "shaders/lift_accumulate.wgsl"]),
    ("# PROTOCOL.md: Default xi", ["PROTOCOL.md"]),
    ("Write ``OUT/tables.md`` atomically", []),
    ("at https://example.org/a/b.py and /tmp/x/y.py", []),
    ("results.json, tables.md, 0.3.py", []),
])
def test_path_tokens(text, expect):
    assert named_paths(text) == expect


def test_missing_paths_are_reported():
    files = ["r360gpu/report/results_io.py", "docs/protocol.md", "bench/x/README.md"]
    assert exists("report/results_io.py", "r360gpu/report/html.py", files)
    assert exists("../README.md", "bench/x/y/z.py", files)
    assert exists("scripts/run_pipeline.py", "r360gpu/bundle/load.py", files)  # another project's
    assert not exists("notes/issue6_design.md", "r360gpu/report/results_io.py", files)
    assert not exists("PROTOCOL.md", "tests/test_protocol_constants.py", files)
