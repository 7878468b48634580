"""--views / EvaluateOptions.views: one case-sensitive glob rule, applied once per scene, the same for
a bundle folder, a loaded Bundle, METHOD=FOLDER groups and a scene built from objects."""
from __future__ import annotations

import numpy as np
import pytest

from badinput_cases import SCORE_FLAGS, renders_bundle
from bundle_factory import make_remove360, write_mask, write_rgb
from r360gpu.bundle import load_bundle, scene_from_objects
from r360gpu.bundle.views import matching, narrow_views
from r360gpu.cli import main
from r360gpu.errors import InputError
from r360gpu.io import load_mask
from r360gpu.pipeline import EvaluateOptions, evaluate

OPTS = dict(n_boot=20, n_perm=10, boundary=False, pictures=False, controls=False)


def test_matching_is_case_sensitive_and_keeps_order():
    names = ["view_001", "View_002", "view_010", "VIEW_003"]
    assert matching(names, "View_00*") == ["View_002"]
    assert matching(names, "view_0?[01]") == ["view_001", "view_010"]
    assert matching(names, "view_001") == ["view_001"]
    assert matching(names, "VIEW_001") == []
    assert matching(names, "[vV]iew_00*") == ["view_001", "View_002"]


@pytest.fixture
def folder(tmp_path):
    """A renders-only bundle with views view_00..view_02 and one more, View_03, that differs in case."""
    root = renders_bundle(tmp_path / "b")
    write_mask(root / "masks" / "View_03.png")
    for src, seed in (("pre", 3), ("a", 13)):
        write_rgb(root / src / "rgb" / "View_03.png", seed=seed)
        np.save(root / src / "depth" / "View_03.npy", np.load(root / src / "depth" / "view_00.npy"))
    return root


def test_a_folder_selects_by_case(folder):
    assert load_bundle(folder).views == ["View_03", "view_00", "view_01", "view_02"]
    assert load_bundle(folder, views=["view_0*"]).views == ["view_00", "view_01", "view_02"]
    assert load_bundle(folder, views=["View_0*"]).views == ["View_03"]


def _objects(folder):
    b = load_bundle(folder)
    return scene_from_objects("r", b.prompt, {v: load_mask(b.masks[v]) for v in b.views}, b.pre, dict(b.methods))


def test_folder_bundle_and_objects_select_the_same_views(folder, ctx):
    opts = EvaluateOptions(views=("view_0[12]", "View_*"), **OPTS)
    runs = {"folder": evaluate(folder, options=opts, device=ctx, progress=False),
            "bundle": evaluate(load_bundle(folder), options=opts, device=ctx, progress=False),
            "objects": evaluate(_objects(folder), options=opts, device=ctx, progress=False)}
    for name, res in runs.items():
        scene = res["scenes"]["r"]
        assert scene["views"] == ["View_03", "view_01", "view_02"], name
        assert [r["view"] for r in scene["methods"]["a"]["views"]] == scene["views"], name
    axes = {name: res["scenes"]["r"]["methods"]["a"]["axes"] for name, res in runs.items()}
    assert axes["folder"] == axes["bundle"] == axes["objects"]


def test_a_bundle_is_selected_once(folder):
    b = load_bundle(folder, views=["view_0[12]"])
    assert b.view_patterns == ("view_0[12]",)
    assert narrow_views(b, ["view_0[12]"]) is b  # loaded with these patterns: nothing to do again
    objects = _objects(folder)
    narrowed = narrow_views(objects, ("view_0[12]",))
    assert narrowed.views == ["view_01", "view_02"] and set(narrowed.masks) == {"view_01", "view_02"}
    assert objects.views == ["View_03", "view_00", "view_01", "view_02"]  # the caller's scene is not changed


def test_a_pattern_that_selects_nothing_names_it_and_the_scene(folder, ctx):
    with pytest.raises(InputError, match=r"--views 'View_00\*' matches no evaluation view of scene 'r'"):
        evaluate(_objects(folder), options=EvaluateOptions(views=("View_00*",), **OPTS), device=ctx, progress=False)
    with pytest.raises(InputError, match="'view_09' is not an evaluation view") as e:
        narrow_views(load_bundle(folder), ["view_00", "view_09"])
    assert e.value.path == str(folder / "scene.toml")


def test_cli_method_folders_pattern_that_selects_nothing(tmp_path, capsys):
    a, b = make_remove360(tmp_path / "A"), make_remove360(tmp_path / "B")
    argv = ["score", f"A={a}", f"B={b}", "--out", str(tmp_path / "o"), *SCORE_FLAGS]
    assert main([*argv, "--views", "View_0*"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "'View_0*'" in err and str(a) in err and "case-sensitive" in err
    assert not (tmp_path / "o" / "results.json").exists()
