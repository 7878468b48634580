"""[expected.METHOD] in scene.toml: parsed, validated, and written by the synthetic benchmark."""
from __future__ import annotations

import tomllib

from r360gpu.bundle.expected import parse_expected
from r360gpu.synthetic.bundle import scene_toml
from r360gpu.synthetic.methods import EXPECTED, METHODS


def _parse(table, methods=("a", "b")):
    problems = []
    return parse_expected(table, list(methods), problems.append), problems


def test_valid_table_is_normalised():
    out, problems = _parse({"a": {"failure": " residue ", "caught_by": ["s_str", "s_sem"]},
                            "b": {"failure": "none"}})
    assert problems == []
    assert out == {"a": {"failure": "residue", "caught_by": ["s_sem", "s_str"]},
                   "b": {"failure": "none", "caught_by": []}}


def test_every_problem_is_named():
    out, problems = _parse({"zz": {"failure": "x"}, "a": {"failure": "", "caught_by": ["s_sem"]},
                            "b": {"failure": "x", "caught_by": ["rqs"], "extra": 1}})
    assert out == {}
    assert any("[expected.zz] names no method" in p for p in problems)
    assert any("[expected.a]: 'failure' must be a non-empty string" in p for p in problems)
    assert any("unknown key 'extra' in [expected.b]" in p for p in problems)
    assert any("[expected.b]: 'caught_by' must be a list of axes" in p for p in problems)
    assert _parse("nope")[1] and _parse({"a": 3})[1]


def test_synthetic_scene_toml_carries_every_methods_expectation():
    class _Scene:
        name, prompt = "room", "sofa"

    text = scene_toml(_Scene(), list(METHODS), seed=0, cameras="cameras")
    data = tomllib.loads(text)
    out, problems = _parse(data["expected"], list(data["methods"]))
    assert problems == [] and set(out) == set(METHODS)
    for m, (failure, axes) in EXPECTED.items():
        assert out[m] == {"failure": failure, "caught_by": list(axes)}
