"""``r360gpu check``: every problem printed (one line each, file first), summary, exit codes."""
from __future__ import annotations

import os

import pytest

import r360gpu.cli as cli
from bundle_factory import make_bundle, make_remove360


@pytest.fixture(autouse=True)
def _only_check(monkeypatch):
    # Build the parser with this sub-command alone: the test does not depend on the others.
    monkeypatch.setattr(cli, "_COMMANDS", ["check"])


def test_valid_bundles_exit_0(tmp_path, capsys):
    a = make_bundle(tmp_path / "a")
    b = make_remove360(tmp_path / "b")
    assert cli.main(["check", str(a), str(b)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == (f"{a}: OK (scene 'room' [scene.toml], prompt 'sofa', 3 views, cameras from {a / 'cameras'}; "
                      f"pre (splat), reference (splat); methods: clean (splat), objectclear (renders))")
    assert out[1] == (f"{b}: OK (scene 'b' [remove360], prompt 'table', 3 views; pre (renders), no reference; "
                      f"methods: after (renders))")
    assert out[2] == "2 bundles checked: 2 valid, 0 invalid"


def test_problems_are_listed_and_exit_2(tmp_path, capsys):
    good = make_bundle(tmp_path / "good")
    bad = make_bundle(tmp_path / "bad")
    os.remove(bad / "pre.ply")
    os.remove(bad / "masks" / "view_01.png")  # view_01 is no longer an evaluation view
    (bad / "scene.toml").write_text((bad / "scene.toml").read_text().replace("prompt", "promptt"))
    assert cli.main(["check", str(good), str(bad)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{good}: OK")
    problems = out[1:-2]
    assert problems == [
        f"{bad / 'scene.toml'}: unknown key 'promptt' (did you mean 'prompt'?)",
        f"{bad / 'scene.toml'}: missing required key 'prompt': the category of the removed object, "
        f"e.g. prompt = \"sofa\"",
        f"{bad / 'pre.ply'}: no such file (scene of [pre])",
    ]
    assert out[-2] == f"{bad}: INVALID ({len(problems)} problems)"
    assert out[-1] == f"2 bundles checked: 1 valid, 1 invalid ({len(problems)} problems)"


def test_options_are_passed_on(tmp_path, capsys):
    root = make_remove360(tmp_path / "s", prompt=None)
    assert cli.main(["check", str(root)]) == 2
    out = capsys.readouterr().out
    assert "no prompt" in out and f"{root}: INVALID (1 problem)" in out
    assert cli.main(["check", "--views", "view_00", "--views", "view_02", str(root), "--prompt", "lamp",
                     "--method-name", "gc"]) == 0
    out = capsys.readouterr().out
    assert "prompt 'lamp', 2 views;" in out and "methods: gc (renders)" in out


def test_missing_bundle(tmp_path, capsys):
    assert cli.main(["check", str(tmp_path / "nope")]) == 2
    assert capsys.readouterr().out.splitlines() == [f"{tmp_path / 'nope'}: no such bundle folder",
                                                    f"{tmp_path / 'nope'}: INVALID (1 problem)"]
