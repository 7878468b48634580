"""Named shader bindings: the host states the WGSL name of each position it binds, and a shader that
declares another name there is refused when the pipeline is made, with a message naming both."""
from __future__ import annotations

import pytest

from r360gpu.gpu import shaders
from r360gpu.gpu.shaders import _bindings_of, check_bindings, shader_bindings
from r360gpu.kernels import depth_change, mask_iou, ssim
from r360gpu.viewer import overlays

WGSL = """
// @group(0) @binding(9) var<storage, read> commented_out: array<u32>;
@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> a_words: array<vec4<u32>>;
@binding(2) @group(0)
var<storage, read_write> out: array<atomic<u32>>;
@group(1) @binding(0) var<storage, read> other: array<f32>;
@group(0) @binding(3) var tex: texture_2d<f32>;
"""


def test_bindings_are_read_from_the_wgsl():
    assert _bindings_of(WGSL) == {0: {0: "P", 1: "a_words", 2: "out", 3: "tex"}, 1: {0: "other"}}


@pytest.fixture
def fake_shader(monkeypatch):
    monkeypatch.setattr(shaders, "load_shader_source", lambda name: WGSL)


def test_matching_names_pass_and_none_is_unchecked(fake_shader):
    check_bindings("k", ("P", "a_words", "out"))
    check_bindings("k", ("P", None, "out", "tex"))
    check_bindings("k", ("other",), group=1)


def test_a_swapped_binding_is_refused_with_both_names(fake_shader):
    with pytest.raises(ValueError, match=r"k\.wgsl, group 0: @binding\(1\) is 'a_words' in the WGSL, "
                                         r"the host binds 'out' there; @binding\(2\) is 'out'"):
        check_bindings("k", ("P", "out", "a_words"))
    with pytest.raises(ValueError, match=r"declares no @binding\(5\), the host binds 'extra'"):
        check_bindings("k", ("P", "a_words", "out", "tex", None, "extra"))


@pytest.mark.parametrize("module", [depth_change, mask_iou, ssim, overlays])
def test_the_kernels_bind_what_their_shaders_declare(module):
    check_bindings(module.SHADER, module.BINDINGS)
    assert list(shader_bindings(module.SHADER)) == list(range(len(module.BINDINGS)))


def test_the_pipeline_refuses_a_swap(ctx):
    names = list(mask_iou.BINDINGS)
    names[1], names[3] = names[3], names[1]
    with pytest.raises(ValueError, match="mask_iou.wgsl"):
        ctx.pipeline(mask_iou.SHADER, "area", bindings=names)
    assert ctx.pipeline(mask_iou.SHADER, "area", bindings=mask_iou.BINDINGS) is not None
