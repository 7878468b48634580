"""A scene far from its coordinates' origin renders as it does around the origin: the device stores
centres relative to `r360gpu.render.scene.storage_origin` (a frame with a large shift, as
bench/frame_invariance_sweep.py draws, otherwise loses the lifted set and s_sem / s_geo to the
projection's float32 sums)."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.io import Gaussians
from r360gpu.io.frames import Frame
from r360gpu.render import Renderer
from r360gpu.render.scene import storage_origin
from r360gpu.synthetic import make_scene

#: A shift of ~5,000 room radii.  The room's centres are put on a 2^-8 grid first, so that every
#: shifted centre (|x| < 2^15) is exactly a float32: both scenes hold the same geometry, bit for bit.
SHIFT = np.array([20000.0, -12000.0, 9000.0])
GRID = 256.0


@pytest.fixture(scope="module")
def room():
    scene = make_scene("room", n_views=3, width=96, height=72, detail=0.25)
    g = scene.pre.with_sh_degree(0)
    means = np.round(np.asarray(g.means, np.float64) * GRID) / GRID
    return Gaussians(means, g.scales, g.quats, g.opacities, g.sh), list(scene.cameras)


def test_a_scene_around_its_origin_is_stored_as_it_is(room):
    g, _ = room
    assert not storage_origin(g.means).any()
    assert not storage_origin(np.zeros((0, 3))).any()
    far = storage_origin(np.asarray(g.means) + SHIFT)
    lo, hi = g.means.min(axis=0) + SHIFT, g.means.max(axis=0) + SHIFT
    np.testing.assert_allclose(far, (lo + hi) / 2)


def test_a_shifted_scene_renders_as_the_scene_at_the_origin(room, ctx):
    g, cams = room
    shifted = Gaussians(np.asarray(g.means, np.float64) + SHIFT, g.scales, g.quats, g.opacities, g.sh)
    assert np.array_equal(np.asarray(shifted.means, np.float32).astype(np.float64) - SHIFT, g.means)
    m = np.eye(4)
    m[:3, 3] = SHIFT
    frame = Frame.from_matrix(m, "shift")
    a, b = Renderer(g, ctx=ctx), Renderer(shifted, ctx=ctx)
    try:
        for cam in cams:
            ra, rb = a.render(cam), b.render(frame.camera(cam))
            assert np.abs(ra.alpha - rb.alpha).max() < 1e-4
            assert np.abs(ra.rgb - rb.rgb).max() < 1e-4
            cover = ra.alpha > 0.5
            np.testing.assert_allclose(rb.depth[cover], ra.depth[cover], rtol=1e-5)
    finally:
        a.release()
        b.release()
