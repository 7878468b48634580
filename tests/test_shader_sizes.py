"""Workgroup and block sizes are stated once, in the WGSL, and the host reads them from there.

r360gpu.gpu.shaders parses ``const NAME: u32 = ...;`` and ``@workgroup_size(...)``; the host modules
(render/, kernels/, viewer/overlays.py) take their dispatch sizes from it.  These tests check the
parser, that every host figure equals the shader's, and that no kernel states a size twice.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from r360gpu import protocol
from r360gpu.gpu import shaders as S

PKG = Path(S.__file__).resolve().parent.parent


def test_parser_reads_literals_consts_and_expressions(monkeypatch):
    src = """
const WG: u32 = 64u;
const ITEMS: u32 = 32u;
const BLOCK: u32 = WG * ITEMS;  // 2048
const BITS: u32 = 4u;
const RADIX: u32 = 1u << BITS;
const HALF: u32 = (WG + 2u) / 2u - 1u;
const F: f32 = 3.5;
const SKIP: u32 = bitcast<u32>(1.0);
@compute @workgroup_size(WG)
fn a(@builtin(local_invocation_index) i: u32) {}
@compute @workgroup_size(8, 4)
fn b() {}
@compute
@workgroup_size(WG, 2u, 1)
fn c() {}
"""
    monkeypatch.setattr(S, "load_shader_source", lambda name: src)
    assert S.shader_constants("x") == {"WG": 64, "ITEMS": 32, "BLOCK": 2048, "BITS": 4, "RADIX": 16, "HALF": 32}
    assert S.workgroup_size("x", "a") == (64, 1, 1)
    assert S.workgroup_size("x", "b") == (8, 4, 1) and S.workgroup_threads("x", "b") == 32
    assert S.workgroup_size("x", "c") == (64, 2, 1)
    with pytest.raises(KeyError, match="no compute entry point 'd'"):
        S.workgroup_size("x", "d")
    with pytest.raises(KeyError, match="declares no u32 const NOPE"):
        S.shader_constant("x", "NOPE")


def test_host_sizes_equal_the_shaders():
    from r360gpu.kernels import depth_change, mask_iou, ssim
    from r360gpu.render import shader_pipelines as kernels, project, scan, sort

    c = S.shader_constants("prefix_sum")
    assert scan.BLOCK == c["BLOCK"] == S.workgroup_threads("prefix_sum", "scan_blocks") * c["ITEMS"]
    c = S.shader_constants("radix_sort")
    assert sort.BLOCK == c["BLOCK"] == S.workgroup_threads("radix_sort", "histogram") * c["ITEMS"]
    assert sort.RADIX == 1 << sort.DIGIT_BITS == c["RADIX"]
    assert project.WG == S.workgroup_threads("render_project")
    assert mask_iou.WG == S.shader_constant("mask_iou", "WG")
    assert (ssim.WG, ssim.RB, ssim.SQ) == tuple(S.shader_constant("ssim", k) for k in ("WG", "RB", "SQ"))
    # depth_change bins the |dD| histogram on the GPU: its bin count is the protocol's GHT bin count
    assert depth_change.N_BINS == S.shader_constant("depth_change", "N_BINS") == protocol.GHT_BINS
    assert depth_change.QV == S.shader_constant("depth_change", "QV")
    assert depth_change._PX_PER_GROUP["histo_private"] == (
        S.workgroup_threads("depth_change", "histo_private") * S.shader_constant("depth_change", "HQ") * 4)
    # workgroup_scan.wgsl: SCAN_SEG x SCAN_SEG threads, its workgroup arrays sized for the largest user
    scan_src = S.load_shader_source("workgroup_scan")
    cap = int(re.search(r"scan_lo: array<vec4<u32>, (\d+)>", scan_src).group(1))
    seg_cap = int(re.search(r"scan_seg_lo: array<vec4<u32>, (\d+)>", scan_src).group(1))
    for name, seg in kernels.SCAN_SEGMENTS.items():
        wg = S.shader_constant(name, "WG")
        assert seg * seg == wg <= cap and seg <= seg_cap, name
    # render_rasterize: THREADS names its workgroup's invocation count
    assert S.workgroup_threads("render_rasterize") == S.shader_constant("render_rasterize", "THREADS")


def _entry_points(src: str):
    return re.findall(r"@workgroup_size\(([^)]*)\)\s*fn\s+(\w+)", src)


@pytest.mark.parametrize("name", S.available_shaders(include_only=False))
def test_one_dimensional_workgroup_sizes_are_named_constants(name):
    # A literal @workgroup_size(256) next to `* 256u` in the body is the same size written twice.
    # 2-D tiles (render_rasterize 8x4, viewer_overlay 8x8) are read whole by the host or checked above.
    for args, entry in _entry_points(S.load_shader_source(name)):
        dims = [d.strip() for d in args.split(",") if d.strip()]
        if len(dims) == 1:
            assert re.fullmatch(r"[A-Z_][A-Z0-9_]*", dims[0]), f"{name}.wgsl {entry}: @workgroup_size({args})"


def test_every_kernel_entry_point_parses():
    for name in S.available_shaders(include_only=False):
        for _, entry in _entry_points(S.load_shader_source(name)):
            assert math.prod(S.workgroup_size(name, entry)) >= 1


def test_no_must_match_comments_left():
    hits = [f"{p.relative_to(PKG.parent)}:{i}" for p in sorted(PKG.rglob("*.py"))
            for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
            if re.search(r"must match the shader|shader constant [A-Z]", line)]
    assert not hits, hits
