"""Named shader bindings: the host states the WGSL name of each position it binds, and a shader that
declares another name there is refused when the pipeline is made, with a message naming both."""
from __future__ import annotations

import pytest

from r360gpu.gpu import shaders
from r360gpu.gpu.shaders import _bindings_of, check_bindings, shader_bindings
from r360gpu.gpu.context import GpuContext
from r360gpu.io.gaussians import random_gaussians
from r360gpu.kernels import depth_change, mask_iou, ssim
from r360gpu.lift import device as lift_device
from r360gpu.render import Renderer, binning, project, rasterize, scan, sort
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


#: Every (shader, host names) the renderer and the lifting pass build pipelines with.
RENDER_AND_LIFT = [("render_project", project.PROJECT_BINDINGS), ("render_bin", binning.BIN_BINDINGS),
                   ("render_ranges", binning.RANGES_BINDINGS), ("prefix_sum", scan.SCAN_BINDINGS),
                   *((name, sort.SORT_BINDINGS) for name in sort.VARIANTS.values()),
                   ("render_rasterize", rasterize.RASTERIZE_BINDINGS),
                   ("render_interleave", rasterize.INTERLEAVE_BINDINGS),
                   ("lift_accumulate", lift_device.BINDINGS)]


@pytest.mark.parametrize("shader, names", RENDER_AND_LIFT, ids=[n for n, _ in RENDER_AND_LIFT])
def test_the_render_and_lift_passes_bind_what_their_shaders_declare(shader, names):
    check_bindings(shader, names)
    assert list(shader_bindings(shader)) == list(range(len(names)))


def _swapped_shaders(tmp_path, monkeypatch, shader: str, a: int, b: int) -> None:
    """Every shader copied to tmp_path, with ``@binding(a)`` and ``@binding(b)`` of ``shader`` swapped,
    and the shader folder pointed there."""
    for name in shaders.available_shaders():
        text = shaders.shader_path(name).read_text(encoding="utf-8")
        if name == shader:
            text = (text.replace(f"@binding({a})", "@binding(SWAP)").replace(f"@binding({b})", f"@binding({a})")
                    .replace("@binding(SWAP)", f"@binding({b})"))
        (tmp_path / f"{name}.wgsl").write_text(text, encoding="utf-8")
    monkeypatch.setenv("R360GPU_SHADER_DIR", str(tmp_path))


def test_a_swapped_rasteriser_binding_fails_with_its_names(ctx, tmp_path, monkeypatch):
    """Two output planes swapped in the WGSL: the render is refused, naming the shader and both
    bindings, instead of giving an image with red and green exchanged."""
    _swapped_shaders(tmp_path, monkeypatch, "render_rasterize", 6, 7)
    fresh = GpuContext(ctx.device)  # its own shader and pipeline caches
    renderer = Renderer(random_gaussians(50, sh_degree=0, seed=1), ctx=fresh)
    cam = small_camera()
    with pytest.raises(ValueError, match=r"render_rasterize\.wgsl, group 0: @binding\(6\) is 'out_g' in the WGSL, "
                                         r"the host binds 'out_r' there; @binding\(7\) is 'out_r'"):
        renderer.render(cam)
    renderer.release()


def test_a_swapped_lift_binding_fails_with_its_names(ctx, tmp_path, monkeypatch):
    """The mask and the accumulators swapped in lift_accumulate.wgsl: lifting is refused by name."""
    import numpy as np

    from r360gpu.lift import MaskLifter

    _swapped_shaders(tmp_path, monkeypatch, "lift_accumulate", 5, 6)
    lifter = MaskLifter(random_gaussians(50, sh_degree=0, seed=1), ctx=GpuContext(ctx.device))
    cam = small_camera()
    with pytest.raises(ValueError, match=r"lift_accumulate\.wgsl, group 0: @binding\(5\) is 'acc' in the WGSL, "
                                         r"the host binds 'mask' there"):
        lifter.add_view(cam, np.ones((cam.height, cam.width), bool))
    lifter.release()


def test_a_swapped_projection_binding_fails_before_anything_renders(ctx, tmp_path, monkeypatch):
    _swapped_shaders(tmp_path, monkeypatch, "render_project", 3, 4)
    renderer = Renderer(random_gaussians(50, sh_degree=0, seed=1), ctx=GpuContext(ctx.device))
    with pytest.raises(ValueError, match=r"render_project\.wgsl, group 0: @binding\(3\) is 'conic'"):
        renderer.render(small_camera())
    renderer.release()


def small_camera():
    from test_render_pipeline import camera

    return camera(40, 24, z=3.0)
