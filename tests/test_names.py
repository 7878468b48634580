"""One table of hostile names through every door a name comes in (class 2 of docs/input-validation.md).

The same names go through scene.toml (method and scene names), ``METHOD=FOLDER`` pairs on the command
line, :func:`~r360gpu.bundle.scene_from_objects` (scene, method and view names) and
:func:`r360gpu.evaluate` given a hand-made :class:`~r360gpu.bundle.Bundle`; each door must refuse
exactly the names the others refuse (one check: :mod:`r360gpu.bundle.names`), naming the name, before
any work and without writing anything.
"""
from __future__ import annotations

import dataclasses
import sys
import json

import pytest

from badinput_cases import SCORE_FLAGS, renders_bundle
from bundle_factory import camera, make_bundle, make_remove360, mask_image, write_mask
import r360gpu.pipeline  # noqa: F401 (loads r360gpu.pipeline.evaluate)
from r360gpu import cli
from r360gpu.bundle import load_bundle, scene_from_objects
from r360gpu.bundle.names import bad_name, name_problems
from r360gpu.errors import InputError
from r360gpu.io import load_colmap, save_colmap

# (name, refused as a method name, refused as a scene or view name)
NAMES = [
    ("mine", False, False),
    ("méthode", False, False),
    ("a b", False, False),
    ("v1.2", False, False),
    ("pre", True, False),          # the pre source's name: a control's cells are cached under it
    ("PRE", True, False),
    ("Reference", True, False),
    ("..", True, True),
    (".", True, True),
    ("../up", True, True),
    ("a/b", True, True),
    ("a\\b", True, True),
    ("", True, True),
    ("  ", True, True),
    (" lead", True, True),
    ("trail ", True, True),
    ("tab\there", True, True),
    ("new\nline", True, True),
    ("nul\x00byte", True, True),
    ("CON", True, True),
    ("a:b", True, True),           # not a file name on Windows, like CON
    ("v1|v2?", True, True),
    ("x" * 201, True, True),
]
IDS = [repr(n)[:24] for n, _, _ in NAMES]


def _refused(fn) -> str | None:
    try:
        fn()
    except InputError as e:
        return str(e)
    return None


def test_table_matches_the_one_check():
    for name, as_method, as_other in NAMES:
        assert bool(name_problems("method", [name], reserved=("pre", "reference"))) == as_method, name
        assert (bad_name(name) is not None) == as_other, name


# --- scene.toml -------------------------------------------------------------------------------------

def _toml_string(s: str) -> str:
    return json.dumps(s)  # a TOML basic string has JSON's escapes


@pytest.mark.parametrize("name,as_method,as_other", NAMES, ids=IDS)
def test_scene_toml(name, as_method, as_other, tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    text = (b / "scene.toml").read_text(encoding="utf-8")
    text = text.replace("[methods.a]", f"[methods.{_toml_string(name)}]").replace(
        'name = "r"', f"name = {_toml_string(name)}")
    (b / "scene.toml").write_text(text, encoding="utf-8")
    rc = cli.main(["check", str(b)])
    out = capsys.readouterr()
    assert "Traceback" not in out.out + out.err
    assert rc == (2 if (as_method or as_other) else 0), out
    if rc == 2:
        assert "name" in out.out and "scene.toml" in out.out


@pytest.mark.parametrize("first,second", [("A", "a"), ("Mine", "MINE")])
def test_scene_toml_names_differing_only_in_case(first, second, tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    text = (b / "scene.toml").read_text(encoding="utf-8").replace("[methods.a]", f"[methods.{first}]")
    text += f'\n[methods.{second}]\nrenders = "a"\n'
    (b / "scene.toml").write_text(text, encoding="utf-8")
    assert cli.main(["check", str(b)]) == 2
    assert "differ only in case" in capsys.readouterr().out


# --- METHOD=FOLDER ------------------------------------------------------------------------------------

@pytest.mark.parametrize("name,as_method,as_other", NAMES, ids=IDS)
def test_method_folder_pairs(name, as_method, as_other, tmp_path, capsys):
    folder = make_remove360(tmp_path / "runs" / "m" / "room_table")
    out = tmp_path / "out"
    rc = cli.main(["score", f"{name}={folder}", "--out", str(out), *SCORE_FLAGS])
    text = "".join(capsys.readouterr())
    assert "Traceback" not in text
    if as_method:
        assert rc == 2, text
        assert not (out / "results.json").exists()
        assert not (tmp_path / "up").exists() and not (tmp_path / "runs" / "up").exists()
    else:
        assert rc == 0, text
        res = json.loads((out / "results.json").read_text())
        assert list(res["scenes"]["room_table"]["methods"]) == [name]


def test_method_folder_pairs_differing_only_in_case(tmp_path, capsys):
    a = make_remove360(tmp_path / "x" / "room_table")
    b = make_remove360(tmp_path / "y" / "room_table")
    rc = cli.main(["score", f"A={a}", f"a={b}", "--out", str(tmp_path / "out"), *SCORE_FLAGS])
    assert rc == 2 and "differ only in case" in capsys.readouterr().err


@pytest.mark.parametrize("arg", ["=folder", "A="])
def test_method_folder_pair_with_a_missing_half(arg, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["score", arg, "--out", str(tmp_path / "out"), *SCORE_FLAGS]) == 2
    assert "METHOD=FOLDER" in capsys.readouterr().err


# --- the library ----------------------------------------------------------------------------------------

def _objects(tmp_path, *, scene="s", method="m", view="v"):
    b = renders_bundle(tmp_path / "lib")
    spec_pre = load_bundle(b).pre
    spec_a = load_bundle(b).methods["a"]
    return lambda: scene_from_objects(scene, "box", {view: mask_image() > 0}, spec_pre, {method: spec_a})


@pytest.mark.parametrize("name,as_method,as_other", NAMES, ids=IDS)
def test_scene_from_objects(name, as_method, as_other, tmp_path):
    for role, refused in (("method", as_method), ("scene", as_other), ("view", as_other)):
        why = _refused(_objects(tmp_path, **{role: name}))
        assert (why is not None) == refused, (role, name, why)
        if why:
            assert role in why and repr(name) in why, why


@pytest.mark.parametrize("name,as_method,as_other", NAMES, ids=IDS)
def test_evaluate_with_a_bundle_made_by_hand(name, as_method, as_other, tmp_path, monkeypatch):
    """A Bundle built by hand skips scene.toml; evaluate() checks its names before any work."""
    ev = sys.modules["r360gpu.pipeline.evaluate"]

    bundle = load_bundle(renders_bundle(tmp_path / "b"))
    reached = []
    monkeypatch.setattr(ev, "_evaluate", lambda *a, **k: reached.append(1) or {})
    for role, refused in (("method", as_method), ("scene", as_other), ("view", as_other)):
        if role == "method":
            b = dataclasses.replace(bundle, methods={name: bundle.methods["a"]})
        elif role == "scene":
            b = dataclasses.replace(bundle, name=name)
        else:
            b = dataclasses.replace(bundle, views=[name], masks={name: bundle.masks["view_00"]})
        why = _refused(lambda: ev.evaluate(b, out=tmp_path / "out", progress=False))
        assert (why is not None) == refused, (role, name, why)
        if why:
            assert not (tmp_path / "out").exists()


def test_two_scenes_whose_names_differ_only_in_case(tmp_path):
    ev = sys.modules["r360gpu.pipeline.evaluate"]

    one = load_bundle(renders_bundle(tmp_path / "b1"))
    two = dataclasses.replace(one, name=one.name.upper())
    with pytest.raises(InputError, match="ignoring case"):
        ev.evaluate([one, two], out=None, progress=False)


def test_view_names_from_mask_files_differing_only_in_case(tmp_path, capsys):
    b = renders_bundle(tmp_path / "b")
    (b / "masks" / "VIEW_00.png").write_bytes((b / "masks" / "view_00.png").read_bytes())
    assert cli.main(["check", str(b)]) == 2
    assert "differ only in case" in capsys.readouterr().out


# --- names read from files: COLMAP text keeps them as written -------------------------------------------

def test_colmap_text_keeps_the_spaces_of_an_image_name(tmp_path):
    save_colmap(tmp_path / "m", [camera("a  b.jpg"), camera("c.jpg")], binary=False)
    assert [c.name for c in load_colmap(tmp_path / "m")] == ["a  b.jpg", "c.jpg"]


def test_a_mask_whose_view_nearly_matches_a_camera_is_explained(tmp_path, capsys):
    b = make_bundle(tmp_path / "b")
    save_colmap(b / "cameras", [camera("view_00.jpg"), camera("view_01.jpg"), camera("view  02.jpg")])
    (b / "masks" / "view_02.png").unlink()
    write_mask(b / "masks" / "view 02.png")
    assert cli.main(["check", str(b)]) == 2
    out = capsys.readouterr().out
    assert "'view 02'" in out and "'view  02'" in out and "differ only slightly" in out
