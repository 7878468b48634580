"""Images beyond one buffer binding render in row bands, pixel for pixel as one pass."""
from __future__ import annotations

import numpy as np
import pytest

import render_oracle
from r360gpu.errors import InputError
from r360gpu.gpu import GpuContext
from r360gpu.io.gaussians import random_gaussians
from r360gpu.render import Renderer, render
from r360gpu.render import renderer as render_pipeline
from test_render_pipeline import camera, compare

PLANES = ("rgb", "alpha", "depth", "median_depth")


@pytest.mark.parametrize("size,limit,aa", [((200, 150), 32768, False), ((203, 149), 40960, True),
                                           ((60, 45), 4096, False)])
def test_bands_equal_one_pass(ctx, size, limit, aa):
    g = random_gaussians(250 if limit == 4096 else 1000, sh_degree=3, seed=size[0])
    cam = camera(*size, z=2.5)
    small = GpuContext(ctx.device, limit_binding_bytes=limit)
    banded = Renderer(g, ctx=small, antialiased=aa)
    rows = banded.band_rows(cam)
    assert 16 <= rows < size[1] and rows % 16 == 0
    got = banded.render(cam)
    one = render(g, cam, ctx=ctx, antialiased=aa)
    assert Renderer(g, ctx=ctx).band_rows(cam) == size[1]
    for key in PLANES:
        np.testing.assert_array_equal(getattr(got, key), getattr(one, key), err_msg=key)
    assert got.alpha.max() > 0.9
    if limit == 4096:
        compare(got, render_oracle.render(g, cam))
    # A renderer reused across sizes: banded, then one pass, then banded again.
    np.testing.assert_array_equal(banded.render(camera(32, 16, z=2.5)).rgb, render(g, camera(32, 16, z=2.5), ctx=ctx, antialiased=aa).rgb)
    np.testing.assert_array_equal(banded.render(cam).rgb, one.rgb)
    banded.release()


def test_device_output_refuses_what_needs_bands(ctx):
    g = random_gaussians(100, seed=1)
    small = GpuContext(ctx.device, limit_binding_bytes=16384)
    r = Renderer(g, ctx=small)
    with pytest.raises(InputError, match="row bands"):
        r.render_device(camera(200, 150))
    with pytest.raises(InputError, match="too wide"):
        r.render(camera(8192, 32))  # one row of tiles: 8192 x 16 x 4 bytes > 16 KiB
    r.release()


def test_host_memory_limit_is_a_clear_error(ctx, monkeypatch):
    g = random_gaussians(50, seed=2)
    small = GpuContext(ctx.device, limit_binding_bytes=65536)
    monkeypatch.setattr(render_pipeline, "_available_memory", lambda: 1 << 20)
    r = Renderer(g, ctx=small)
    cam = camera(400, 300, name="big")
    with pytest.raises(InputError, match=r"big: a 400x300 render needs .* GiB of host memory"):
        r.render(cam)
    r.release()


def test_band_rows_for_a_16k_camera(ctx):
    """A 16384 x 16384 camera is planned in bands, before anything is allocated on the device."""
    r = Renderer(random_gaussians(10, seed=3), ctx=ctx)
    rows = r.band_rows(camera(16384, 16384))
    assert 16 <= rows < 16384 and rows % 16 == 0
    per_plane = min(ctx.max_binding_bytes, int(ctx.limits.get("max-buffer-size", 1 << 62)) // 6)
    assert 16384 * rows * 4 <= per_plane
    r.release()
