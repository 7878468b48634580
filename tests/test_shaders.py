"""The shader sources: includes, conventions as override constants, uniforms packed by name, headers."""
from __future__ import annotations

import re

import numpy as np
import pytest

from r360gpu.gpu import shaders
from r360gpu.gpu.shaders import INCLUDE_ONLY, available_shaders, load_shader_source, shader_path
from r360gpu.gpu.uniforms import SCALARS, pack_words, struct_fields
from r360gpu.render import conventions, shader_pipelines as kernels

RENDER_SHADERS = ("render_project", "render_bin", "render_ranges", "render_rasterize", "render_interleave",
                  "prefix_sum", "radix_sort", "radix_sort_blocks")
_COMMENT = re.compile(r"//[^\n]*")
_OVERRIDE = re.compile(r"\boverride\s+(\w+)\s*:\s*\w+\s*(?:=\s*([^;]+))?;")
_CONST = re.compile(r"\bconst\s+(\w+)\s*:")
_FLOAT = re.compile(r"(?<![\w.])(\d+\.\d*(?:e[+-]?\d+)?|\d+e[+-]?\d+)f?(?![\w.])")
# Convention values that must never be written as literals in a render kernel.
_CONVENTION_NAMES = ("TILE", "NEAR_PLANE", "FRUSTUM_GUARD", "COV2D_BLUR", "ALPHA_MAX", "ALPHA_MIN", "T_MIN",
                     "MEDIAN_T", "NO_COVERAGE_ALPHA", "SIGMA_EXTENT", "AA_MIN_RATIO")
_DISTINCTIVE = {conventions.ALPHA_MAX, conventions.ALPHA_MIN, 255.0, conventions.T_MIN, conventions.COV2D_BLUR,
                conventions.AA_MIN_RATIO, conventions.FRUSTUM_GUARD, conventions.NEAR_PLANE}


def _code(name: str) -> str:
    return _COMMENT.sub("", load_shader_source(name))


def test_every_shader_has_a_contract_header_and_compiles(ctx):
    for name in available_shaders():
        text = shader_path(name).read_text(encoding="utf-8")
        header = [ln for ln in text.splitlines()[:3] if ln.startswith("//")]
        assert len(header) >= 2, f"{name}.wgsl needs a header comment saying what it computes"
        ctx.device.create_shader_module(code=load_shader_source(name))
    assert set(INCLUDE_ONLY) <= set(available_shaders())
    assert not set(INCLUDE_ONLY) & set(available_shaders(include_only=False))


def test_include_expands_once_and_refuses_cycles(tmp_path, monkeypatch):
    (tmp_path / "a.wgsl").write_text("// a\n//!include b.wgsl\n//!include c.wgsl\nfn a() {}\n")
    (tmp_path / "b.wgsl").write_text("// b\n//!include c.wgsl\nfn b() {}\n")
    (tmp_path / "c.wgsl").write_text("// c\nfn c() {}\n")
    (tmp_path / "x.wgsl").write_text("//!include y.wgsl\n")
    (tmp_path / "y.wgsl").write_text("//!include x.wgsl\n")
    monkeypatch.setenv("R360GPU_SHADER_DIR", str(tmp_path))
    src = load_shader_source("a")
    assert src.count("fn c()") == 1 and src.count("fn b()") == 1
    assert src.index("fn c()") < src.index("fn b()") < src.index("fn a()")
    with pytest.raises(ValueError, match="cycle"):
        load_shader_source("x")
    assert shaders.load_shader_source("c") == "// c\nfn c() {}\n"


def test_linear_workgroup_index_is_written_once():
    for name in available_shaders():
        text = _COMMENT.sub("", shader_path(name).read_text(encoding="utf-8"))
        count = text.count("wid.x + wid.y * nwg.x")
        assert count == (1 if name == "common" else 0), name


def test_conventions_reach_the_render_shaders_as_overrides():
    """Fails when a render kernel holds its own copy of a convention (a literal or a const)
    or when a pipeline would be built without the value conventions.py defines."""
    for name in RENDER_SHADERS:
        code = _code(name)
        declared = dict(_OVERRIDE.findall(code))
        given = kernels.constants(name)
        assert set(declared) == set(given), (name, sorted(declared), sorted(given))
        for const in _CONST.findall(code):
            assert const not in _CONVENTION_NAMES, f"{name}.wgsl: const {const} duplicates conventions.py"
        for lit in _FLOAT.findall(code):
            assert float(lit) not in _DISTINCTIVE, f"{name}.wgsl: literal {lit} duplicates a value of conventions.py"
        for key, value in given.items():
            if key in _CONVENTION_NAMES:
                assert value == pytest.approx(float(getattr(conventions, key)), rel=0, abs=0), (name, key)
    # Every override name of the table is a conventions.py name with its value.
    for name, table in conventions.SHADER_CONSTANTS.items():
        for key, value in table.items():
            assert float(getattr(conventions, key)) == value, (name, key)


def test_override_constants_change_the_image(ctx, monkeypatch):
    """The constants really are the kernels' values: changing one changes the render."""
    from r360gpu.io.gaussians import random_gaussians
    from r360gpu.render import render
    from test_render_pipeline import camera

    g = random_gaussians(300, sh_degree=0, seed=1)
    base = render(g, camera(), ctx=ctx)
    table = dict(conventions.SHADER_CONSTANTS["render_project"], COV2D_BLUR=3.0)
    monkeypatch.setitem(conventions.SHADER_CONSTANTS, "render_project", table)
    blurred = render(g, camera(), ctx=ctx)
    assert np.abs(blurred.rgb - base.rgb).max() > 0.05


def test_uniform_structs_are_packed_by_name():
    for name in RENDER_SHADERS:
        fields = struct_fields(name)
        assert fields and all(t in SCALARS for _, t in fields), name
    names = [n for n, _ in struct_fields("render_rasterize")]
    assert names[0] == "width" and names[-1] == "row_base"
    values = {n: i for i, n in enumerate(names)}
    values["bg_r"] = 0.25
    words = pack_words("render_rasterize", values)
    assert words[names.index("bg_r")] == 0.25 and words[names.index("tiles_x")] == names.index("tiles_x")
    with pytest.raises(ValueError, match="missing fields \\['row_base'\\]"):
        pack_words("render_rasterize", {k: v for k, v in values.items() if k != "row_base"})
    with pytest.raises(ValueError, match="unknown fields \\['rowbase'\\]"):
        pack_words("render_rasterize", {**values, "rowbase": 0})


def test_the_compositing_rule_is_written_once():
    """composite.wgsl declares the compositing constants and applies them; the rasteriser and the
    lifting pass include it and name none of those constants themselves."""
    declared = dict(_OVERRIDE.findall(_COMMENT.sub("", shader_path("composite").read_text(encoding="utf-8"))))
    assert set(declared) == set(conventions.COMPOSITE_CONSTANTS)
    for name in ("render_rasterize", "lift_accumulate"):
        raw = shader_path(name).read_text(encoding="utf-8")
        assert "//!include composite.wgsl" in raw, name
        own = _COMMENT.sub("", raw)
        assert "composite(" in own, name
        for const in conventions.COMPOSITE_CONSTANTS:
            assert const not in own, f"{name}.wgsl names {const}: the rule is composite.wgsl's"
