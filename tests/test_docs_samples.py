"""Every command and code sample of README.md and docs/*.md, run as written.

A fenced block is a sample when its language is ``sh`` or ``python``; output, layouts and file
formats are ``text`` and ``toml`` blocks.  The samples run in a workspace laid out like a checkout
after ``./r360 demo --layouts``: a small demo (2 views of 96x72) in ``r360-demo/``, its scenes also in
the layouts of docs/your-scene.md under ``r360-demo/layouts/``, the checkout's ``tests/``
and ``bench/`` beside it, and ``./r360`` standing for the checkout's script with the set-up done
(the environment is the one running this test).  Two commands differ from a user's run, for time:
``./r360 demo`` makes the small demo, and ``./r360 test`` collects the suite instead of running it
(running it is what ``.ci/run`` does).

An HTML comment on the line before a block changes how it is run:

* ``<!-- sample: skip REASON -->``: not run (the list is checked below and must stay short);
* ``<!-- sample: tested-by PATH -->``: run by that test module with inputs it builds;
* ``<!-- sample: setup NAME -->``: the workspace first gets the inputs NAME stands for
  (``onnx-stand-ins``: tiny ONNX graphs with the models' signatures under the sample's paths).

The python blocks of one page run in order in one namespace, as in one ``./r360 python`` session.
``toml`` blocks are scene.toml samples: each is checked by the bundle loader for unknown keys and
bad values.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUN_LANGS = {"sh", "python"}
KNOWN_LANGS = RUN_LANGS | {"text", "toml"}
BLOCK = re.compile(r"(?:^<!-- sample: (?P<marker>[^\n]*?) -->\n)?^```(?P<lang>[^\n`]*)\n(?P<body>.*?)^```$",
                   re.M | re.S)
MAX_SKIPS = 5
DEMO_ARGS = ["--n-views", "2", "--width", "96", "--height", "72", "--n-boot", "200", "--n-perm", "100"]


def _blocks():
    out = []
    for page in PAGES:
        for m in BLOCK.finditer(page.read_text(encoding="utf-8")):
            out.append((page.relative_to(ROOT).as_posix(), m["lang"].strip(), m["marker"] or "", m["body"]))
    return out


BLOCKS = _blocks()
RUN = [b for b in BLOCKS if b[1] in RUN_LANGS and not b[2].startswith(("skip", "tested-by"))]


def _id(block):
    page, lang, _, body = block
    return f"{page}:{lang}:{body.strip().splitlines()[0][:50]}"


def test_every_block_has_a_known_language_and_marker():
    for page, lang, marker, body in BLOCKS:
        assert lang in KNOWN_LANGS, f"{page}: a ``` block needs a language ({sorted(KNOWN_LANGS)}): {body[:60]!r}"
        if marker:
            kind, _, arg = marker.partition(" ")
            assert kind in ("skip", "tested-by", "setup") and arg.strip(), f"{page}: bad marker {marker!r}"
            if kind == "tested-by":
                assert (ROOT / arg.strip()).is_file(), f"{page}: {arg} does not exist"


def test_skipped_samples_are_few_and_give_a_reason():
    skips = [(p, m) for p, _, m, _ in BLOCKS if m.startswith("skip")]
    assert len(skips) <= MAX_SKIPS, skips
    assert all(len(m.split()) >= 5 for _, m in skips), "a skip marker says why"


def test_one_command_spelling():
    """Commands are `./r360 ...` everywhere (a bare `r360gpu` or `python` is not on PATH after set-up)."""
    for page, lang, marker, body in BLOCKS:
        if lang != "sh" or marker.startswith("skip"):
            continue
        continued = False
        for line in body.splitlines():
            words = line.strip().split()
            if words and not continued and not words[0].startswith("#") and "=" not in words[0]:
                assert words[0] == "./r360", f"{page}: {line!r}"
            continued = line.rstrip().endswith("\\")


#: A bench command as the pages write it (through ./r360, or as run on a machine without it), up to the
#: end of its code span, table cell or line; a script named by a placeholder in capitals is not one.
BENCH_COMMAND = re.compile(r"(?:\./r360 python|(?:PYTHONPATH=\. )?python3?) (bench/[a-z]\w*\.py)([^`|\n]*)")


def test_listed_bench_scripts_exist_and_parse_their_options():
    """Bench commands are not run for time (the benchmarks page is their output); every one a page
    gives names a script that exists and starts, with options that script accepts."""
    options: dict[str, set[str]] = {}
    for page in PAGES:
        for script, rest in BENCH_COMMAND.findall(page.read_text(encoding="utf-8")):
            options.setdefault(script, set()).update(re.findall(r"(?<![\w-])--[a-z][\w-]*", rest))
    assert len(options) >= 10
    for s, used in sorted(options.items()):
        proc = subprocess.run([sys.executable, s, "--help"], cwd=ROOT, capture_output=True, text=True,
                              timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert proc.returncode == 0 and "usage" in proc.stdout, f"{s}: {proc.stderr[-500:]}"
        known = set(re.findall(r"(?<![\w-])--[a-z][\w-]*", proc.stdout))
        assert used <= known, f"{s}: the docs give it {sorted(used - known)}, which it does not accept"


@pytest.mark.parametrize("block", [b for b in BLOCKS if b[1] == "toml"], ids=_id)
def test_toml_sample_is_a_valid_scene_toml(block, tmp_path):
    """A scene.toml sample has only keys and values the loader accepts: every problem check_bundle finds
    is about the files it names (absent here), none about scene.toml itself."""
    from r360gpu import check_bundle

    (tmp_path / "scene.toml").write_text(block[3], encoding="utf-8")
    problems = check_bundle(tmp_path)
    assert problems, "check_bundle saw no missing file: the sample names none?"
    assert [str(p) for p in problems if p.path == "scene.toml"] == [], block[0]


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    ws = tmp_path_factory.mktemp("checkout")
    for name in ("tests", "bench"):
        (ws / name).symlink_to(ROOT / name)
    py = shlex.quote(sys.executable)
    script = f"""#!/usr/bin/env bash
# ./r360 with the set-up done: the environment running the test suite.
set -euo pipefail
cmd=${{1:---help}}; [ $# -gt 0 ] && shift
case "$cmd" in
    test) cd {shlex.quote(str(ROOT))} && exec {py} -m pytest --collect-only -q -p no:cacheprovider "$@" ;;
    python) exec {py} "$@" ;;
    docs) cd {shlex.quote(str(ROOT))} && exec {py} -m mkdocs build --strict --site-dir {shlex.quote(str(ws / 'site'))} ;;
    demo) exec {py} -m r360gpu demo "$@" {' '.join(DEMO_ARGS)} ;;
    *) exec {py} -m r360gpu "$cmd" "$@" ;;
esac
"""
    (ws / "r360").write_text(script)
    (ws / "r360").chmod(0o755)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "XDG_RUNTIME_DIR": os.environ.get("XDG_RUNTIME_DIR", "/tmp")}
    proc = subprocess.run(["./r360", "demo", "--quiet", "--layouts"], cwd=ws, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return ws, env


def _setup(name: str, ws: Path) -> None:
    if name == "onnx-stand-ins":
        import numpy as np

        sys.path.insert(0, str(ROOT / "tests"))
        from onnx_graphs import dino_model, sam_decoder, sam_encoder_nchw, write_tokenizer_json

        models = ws / "models"
        models.mkdir(exist_ok=True)
        write_tokenizer_json(models / "tokenizer.json")
        dino_model(models / "groundingdino.onnx", np.zeros((2, 256), np.float32), np.zeros((2, 4), np.float32))
        sam_encoder_nchw(models / "sam2.1_hiera_large.encoder.onnx")
        sam_decoder(models / "sam2.1_hiera_large.decoder.onnx", iou=[0.9] * 4, radius=[100] * 4, slope=[1.0] * 4)
    else:
        raise AssertionError(f"unknown sample setup {name!r}")


@pytest.mark.parametrize("block", [b for b in RUN if b[1] == "sh"], ids=_id)
def test_command_sample(block, workspace):
    ws, env = workspace
    page, _, marker, body = block
    if marker.startswith("setup"):
        _setup(marker.split()[1], ws)
    proc = subprocess.run(["bash", "-euo", "pipefail", "-c", body], cwd=ws, env=env, capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, f"{page}:\n{body}\n--- stdout\n{proc.stdout[-3000:]}\n--- stderr\n{proc.stderr[-3000:]}"


@pytest.mark.parametrize("page", sorted({b[0] for b in RUN if b[1] == "python"}))
def test_python_samples(page, workspace, monkeypatch):
    ws, _ = workspace
    monkeypatch.chdir(ws)
    ns: dict = {"__name__": "__main__"}
    for p, lang, marker, body in RUN:
        if p == page and lang == "python":
            exec(compile(body, page, "exec"), ns)


def test_samples_are_counted():
    """The count the closing note quotes: blocks run here, by other tests, and skipped."""
    run = len(RUN)
    tested_elsewhere = sum(b[2].startswith("tested-by") for b in BLOCKS)
    skipped = sum(b[2].startswith("skip") for b in BLOCKS)
    print(f"samples: {run} run here, {tested_elsewhere} by other tests, {skipped} skipped")
    assert run >= 15
