"""Per-source render settings in scene.toml and ``score --antialiased``: parsed, checked, and reaching the renderer."""
from __future__ import annotations

import numpy as np
import pytest

from bundle_factory import SCENE_TOML, make_bundle
from r360gpu.bundle import BundleError, load_bundle
from r360gpu.bundle.model import PRINCIPAL_POINTS, RENDER_KEYS, RenderSettings
from r360gpu.errors import InputError
from r360gpu.render import conventions
from r360gpu.render.conventions import RenderOptions
from r360gpu.render.sources import open_source


def _with(toml_lines: str, section: str = "[pre]\nscene = \"pre.ply\"\n") -> str:
    return SCENE_TOML.replace(section, section + toml_lines)


def test_settings_parsed_per_source_and_in_the_fingerprint(tmp_path):
    root = make_bundle(tmp_path / "b")
    plain = load_bundle(root)
    assert plain.pre.render == RenderSettings()
    (root / "scene.toml").write_text(
        _with('antialiased = true\nnear = 0.01\nno_coverage_alpha = 0\nprincipal_point = "centre"\n')
        .replace('[methods.clean]\nscene = "methods/clean.ply"\n',
                 '[methods.clean]\nscene = "methods/clean.ply"\nantialiased = true\n'), encoding="utf-8")
    b = load_bundle(root)
    assert b.pre.render == RenderSettings(antialiased=True, near=0.01, no_coverage_alpha=0.0, principal_point="centre")
    assert b.methods["clean"].render.given() == {"antialiased": True}
    assert b.reference.render.given() == {}
    assert b.fingerprint() != plain.fingerprint()
    src = open_source(b.pre)
    assert src.renderer.options == RenderOptions(antialiased=True, near=0.01, no_coverage_alpha=0.0,
                                                 principal_point="centre")
    assert src.describe()["render"]["antialiased"] is True
    src.release()


@pytest.mark.parametrize("line,message", [
    ("antialiased = 1\n", "'antialiased' must be true or false"),
    ("near = 0\n", "'near' must be a positive number"),
    ("near = \"far\"\n", "'near' must be a positive number"),
    ("no_coverage_alpha = 2.0\n", "'no_coverage_alpha' must be a number in [0, 1]"),
    ("principal_point = \"middle\"\n", "'principal_point' must be 'camera' or 'centre'"),
    ("antialias = true\n", "did you mean 'antialiased'"),
])
def test_bad_settings_name_the_file_and_the_key(tmp_path, line, message):
    root = make_bundle(tmp_path / "b", _with(line))
    with pytest.raises(BundleError) as e:
        load_bundle(root)
    assert message in str(e.value) and "scene.toml" in str(e.value) and "[pre]" in str(e.value)


def test_settings_on_renders_are_refused(tmp_path):
    toml = _with("antialiased = true\n", '[methods.objectclear]\nrenders = "methods/objectclear"\n')
    with pytest.raises(BundleError, match=r"\[methods.objectclear\] 'antialiased' apply to splat scenes only"):
        load_bundle(make_bundle(tmp_path / "b", toml))


def test_bundle_and_renderer_accept_the_same_values():
    """The bundle layer cannot import the renderer's validation; both must agree."""
    assert PRINCIPAL_POINTS == conventions.PRINCIPAL_POINTS
    assert set(RENDER_KEYS) == set(RenderOptions.__dataclass_fields__)
    for key, values in {"near": [0.01, 1, 0, -1, float("inf")], "no_coverage_alpha": [0, 0.5, 1, -0.1, 1.1],
                        "principal_point": ["camera", "centre", "center", ""], "antialiased": [True, False, 1]}.items():
        for v in values:
            toml_ok = _accepts_toml(key, v)
            try:
                RenderOptions(**{key: v})
                options_ok = True
            except InputError:
                options_ok = False
            assert toml_ok == options_ok, (key, v)


def _accepts_toml(key, v) -> bool:
    from r360gpu.bundle.scene_toml import _parse_render_settings

    problems = []
    _parse_render_settings({key: v}, "[pre]", problems.append, scene=True)
    return not problems


def test_with_render_settings(tmp_path):
    b = load_bundle(make_bundle(tmp_path / "b"))
    aa = b.with_render_settings(antialiased=True)
    assert aa.pre.render.antialiased and aa.reference.render.antialiased and aa.methods["clean"].render.antialiased
    assert aa.methods["objectclear"] == b.methods["objectclear"]  # renders: images already
    assert b.with_render_settings(antialiased=None) is b
    from r360gpu.io.gaussians import random_gaussians
    from dataclasses import replace

    with pytest.raises(InputError, match="SceneSource"):
        replace(b, pre=random_gaussians(5)).with_render_settings(antialiased=True)


def test_cli_antialiased_reaches_the_sources(tmp_path, capsys):
    import json

    from r360gpu.cli import main

    root = make_bundle(tmp_path / "b")
    args = ["score", str(root), "--views", "view_00", "--no-boundary", "--no-pictures", "--n-boot", "50",
            "--n-perm", "20", "--quiet"]
    assert main(args + ["--out", str(tmp_path / "plain")]) == 0
    assert main(args + ["--out", str(tmp_path / "aa"), "--antialiased"]) == 0
    capsys.readouterr()
    plain = json.loads((tmp_path / "plain" / "results.json").read_text())
    aa = json.loads((tmp_path / "aa" / "results.json").read_text())
    (scene,) = aa["scenes"].values()
    (scene_plain,) = plain["scenes"].values()
    assert scene["sources"]["pre"]["render"]["antialiased"] is True
    assert scene["sources"]["methods"]["clean"]["render"]["antialiased"] is True
    assert scene_plain["sources"]["pre"]["render"]["antialiased"] is False
    assert scene["sources"]["methods"]["objectclear"]["kind"] == "renders"
