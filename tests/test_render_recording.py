"""The renderer's frames of one shape reuse their host recording, and its tile lists keep the oracle's order.

Runs under every sort path (test_render_pipeline's autouse fixture: WGSL sort with
either radix variant, and the host sort).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import render_oracle
from r360gpu.gpu import GpuContext
from r360gpu.io.gaussians import Gaussians, random_gaussians
from r360gpu.render import Renderer
from r360gpu.render.project import tile_grid
from test_render_pipeline import camera, compare, look_at, scene, sort_backend  # noqa: F401 (autouse fixture)

PLANES = ("rgb", "alpha", "depth", "median_depth")


def assert_same(a, b):
    for key in PLANES:
        np.testing.assert_array_equal(getattr(a, key).view(np.uint32), getattr(b, key).view(np.uint32), err_msg=key)


def test_frames_of_one_shape_create_nothing_and_render_the_same(ctx):
    """The second frame of a camera creates no bind group or uniform buffer and rewrites no
    uniform; moving the camera (other key counts, uniforms rewritten in place) and coming
    back gives, bit for bit, what a fresh renderer gives for each view."""
    g = random_gaussians(600, sh_degree=2, seed=5)
    a = camera(67, 45, z=3.0)
    b = look_at([1.5, 0.4, -2.5], [0, 0, 0], 67, 45, 55.0)
    renderer = Renderer(g, ctx=ctx)
    first = renderer.render(a)
    before = dict(renderer.frames.counts)
    again = renderer.render(a)
    after = renderer.frames.counts
    assert after["groups_created"] == before["groups_created"]
    assert after["uniforms_created"] == before["uniforms_created"]
    assert after["uniforms_written"] == before["uniforms_written"]
    assert after["groups_reused"] > before["groups_reused"]
    assert_same(first, again)
    moved = renderer.render(b)
    back = renderer.render(a)
    dev = renderer.render_device(b).to_numpy(ctx)
    renderer.release()
    fresh = {}
    for name, cam in (("a", a), ("b", b)):
        r = Renderer(g, ctx=ctx)
        fresh[name] = r.render(cam)
        r.release()
    assert_same(moved, fresh["b"])
    assert_same(back, fresh["a"])
    assert_same(dev, fresh["b"])
    compare(moved, render_oracle.render(g, b))


class CopyLists:
    """A tile pass (the renderer's public extension point, r360gpu.render.tile_pass) that keeps a
    copy of every key window's tile lists (ranges, Gaussian per key)."""

    def __init__(self):
        self.lists = []

    def record(self, ctx, enc, lists, cam) -> None:
        tiles = lists.window.end - lists.window.begin
        ranges = ctx.buffer(tiles * 8)
        enc.copy_buffer_to_buffer(lists.ranges.buffer, lists.ranges.offset, ranges, 0, tiles * 8)
        vals = ctx.buffer(max(4, lists.num_keys * 4))
        if lists.num_keys:
            enc.copy_buffer_to_buffer(lists.vals, 0, vals, 0, lists.num_keys * 4)
        self.lists.append((ctx, lists.window, ranges, vals, lists.num_keys))


class ListsRenderer(Renderer):
    """A renderer whose render also runs :class:`CopyLists` over the view's tile lists."""

    def render(self, camera):
        out = super().render(camera)
        self.copied = CopyLists()
        self.run_pass(camera, self.copied)
        return out

    def tile_lists(self) -> dict[int, np.ndarray]:
        """Gaussian indices per tile id, in blend order."""
        out = {}
        for ctx, window, ranges, vals, k in self.copied.lists:
            r = ctx.read(ranges, np.uint32, 2 * (window.end - window.begin)).reshape(-1, 2)
            v = ctx.read(vals, np.uint32, k) if k else np.zeros(0, np.uint32)
            for t, (s, e) in enumerate(r):
                out[window.begin + t] = v[s:e]
        return out


def exact_depth_scene(n, width, height, seed, depths=(-0.5, 0.0, 0.25), spread=1.0):
    """Gaussians whose camera depths are a few dyadic values (exact in float32, so the GPU's z is
    known bit for bit): many ties, decided by index."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-spread, spread, (n, 2)) * np.array([width / height, 1.0])
    z = rng.choice(np.asarray(depths), n)
    colors = rng.uniform(0, 1, (n, 3))
    return scene(np.column_stack([xy, z]), 0.08, rng.uniform(0.2, 0.9, n), colors)


def check_order(renderer: ListsRenderer, g, cam, z0: float):
    """Every tile's list is front to back by depth, ties by index (the oracle's stable depth order),
    and covers every tile exactly once."""
    z = np.asarray(g.means, np.float32)[:, 2] + np.float32(z0)
    lists = renderer.tile_lists()
    gx, gy = tile_grid(cam.width, cam.height)
    assert sorted(lists) == list(range(gx * gy))
    rank = np.empty(len(z), np.int64)
    rank[np.argsort(z, kind="stable")] = np.arange(len(z))
    filled = 0
    for seg in lists.values():
        assert len(np.unique(seg)) == len(seg)
        np.testing.assert_array_equal(np.diff(rank[seg.astype(np.int64)]) > 0, True)
        filled += len(seg) > 1
    return filled


@pytest.mark.parametrize("size", [(64, 64), (272, 16), (240, 16), (48, 40)])  # 16, 17, 15 and 12 tiles
def test_tile_lists_follow_the_oracle_order(ctx, size):
    """Equal depths everywhere, tile counts at and around a power of two (the tile sort's bits)."""
    width, height = size
    g = exact_depth_scene(700, width, height, seed=width)
    cam = camera(width, height, z=3.0, f=0.9 * height)
    renderer = ListsRenderer(g, ctx=ctx)
    got = renderer.render(cam)
    assert check_order(renderer, g, cam, 3.0) > 0
    renderer.release()
    compare(got, render_oracle.render(g, cam))


def test_one_tile_holding_every_gaussian(ctx):
    """400 Gaussians in one 16x16 image, 200 of them at the same depth."""
    g = exact_depth_scene(400, 16, 16, seed=3, depths=(0.0, 0.0, 0.5, -0.25), spread=0.3)
    cam = camera(16, 16, z=3.0, f=14.0)
    renderer = ListsRenderer(g, ctx=ctx)
    got = renderer.render(cam)
    check_order(renderer, g, cam, 3.0)
    assert renderer.stats.keys == 400
    renderer.release()
    compare(got, render_oracle.render(g, cam))


def test_lists_over_several_key_windows(ctx):
    """Keys beyond a (lowered) binding: each window's lists keep the order."""
    small = GpuContext(ctx.device, limit_binding_bytes=16384)
    g = exact_depth_scene(900, 64, 48, seed=9)
    g = Gaussians(g.means, np.full((900, 3), 0.3, np.float32), g.quats, g.opacities, g.sh)
    cam = camera(64, 48, z=3.0)
    renderer = ListsRenderer(g, ctx=small)
    got = renderer.render(cam)
    assert renderer.stats.windows > 1
    check_order(renderer, g, cam, 3.0)
    renderer.release()
    compare(got, render_oracle.render(g, cam))


@pytest.mark.parametrize("n", [0, 1])
def test_no_and_one_gaussian(ctx, n):
    """Empty tile lists, or one key; and a second frame of the same shape alike."""
    if n == 0:
        g = SimpleNamespace(means=np.zeros((0, 3), np.float32), scales=np.zeros((0, 3), np.float32),
                            quats=np.zeros((0, 4), np.float32), opacities=np.zeros(0, np.float32),
                            sh=np.zeros((0, 1, 3), np.float32))
    else:
        g = scene([[0.0, 0.0, 0.0]], 0.05, 0.8, [0.2, 0.6, 0.9])
    cam = camera(40, 24, z=3.0)
    renderer = ListsRenderer(g, ctx=ctx)
    got = renderer.render(cam)
    lists = renderer.tile_lists()
    assert sum(len(v) for v in lists.values()) == renderer.stats.keys
    assert all(np.all(v == 0) for v in lists.values())
    assert_same(renderer.render(cam), got)
    renderer.release()
    if n:
        compare(got, render_oracle.render(g, cam))
        assert renderer.stats.keys >= 1
    else:
        assert np.all(got.alpha == 0)


def test_device_interleave_inside_cached_frames(ctx, monkeypatch):
    """The numpy read-back's device interleave (GPU adapters' path) recorded inside cached frames:
    the same planes as the host interleave, frame after frame and after a camera move."""
    g = random_gaussians(400, sh_degree=1, seed=12)
    cams = [camera(67, 45, z=3.0), camera(67, 45, z=3.0), look_at([1.0, 0.3, -2.5], [0, 0, 0], 67, 45, 50.0)]
    got = {}
    for where in ("gpu", "cpu"):
        monkeypatch.setenv("R360GPU_RENDER_INTERLEAVE", where)
        renderer = Renderer(g, ctx=ctx)
        got[where] = [renderer.render(cam) for cam in cams]
        renderer.release()
    for a, b in zip(got["gpu"], got["cpu"]):
        assert_same(a, b)
    assert_same(got["gpu"][0], got["gpu"][1])
