"""Viewer parts without a window: progressive-resolution policy, target estimate, captures,
results parsing, the ``r360gpu view`` command."""
from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from r360gpu.errors import InputError
from viewer_fixtures import orbit_cameras
from r360gpu.viewer.capture import PathRecorder, path_through, save_png
from r360gpu.viewer.quality import ResolutionPolicy
from r360gpu.viewer.results import load_results
from r360gpu.viewer.target import estimate_target


def test_policy_refines_when_still_and_adapts_while_moving():
    p = ResolutionPolicy(still_delay=0.3, frame_budget=0.04)
    assert p.scale(0.0, 10_000) == 0.5  # nothing measured yet: a quarter of the pixels
    assert p.scale(0.3, 10_000) == 1.0
    p.observe(10_000, 0.01)  # fast: the whole frame fits the budget
    assert p.scale(0.1, 10_000) == 1.0
    p = ResolutionPolicy(frame_budget=0.04, smoothing=0.0)
    p.observe(1000, 1.0)  # 1 ms per pixel: far too slow
    assert p.scale(0.0, 1_000_000) == p.min_scale
    p.observe(1_000_000, 0.16)  # 4x over budget -> half the linear size
    assert p.scale(0.0, 1_000_000) == pytest.approx(0.5)
    assert p.quantised(0.53) == 0.5 and p.quantised(0.01) == p.min_scale and p.quantised(1.0) == 1.0
    assert ResolutionPolicy(moving_scale=0.25).scale(0.0, 10) == 0.25
    p.observe(0, 1.0)
    p.observe(10, float("nan"))
    assert p.seconds_per_pixel == pytest.approx(0.16e-6)


def test_target_lifted_from_masks_rejects_what_only_one_view_sees(ctx):
    """The viewer's target is the pipeline's lifted target (r360gpu.lift): a ball seen in every
    mask is target, a Gaussian behind it from one side only and one far away are not."""
    from r360gpu.io.gaussians import Gaussians
    from r360gpu.lift import target_masks

    cams = orbit_cameras(6, 40, 30)
    centre = np.array([0.0, 0.0, 0.35])
    ball = centre + np.random.default_rng(0).normal(scale=0.05, size=(200, 3))
    behind = np.array([[0.0, 2.0, 0.35]])  # near the ball from one side only
    means = np.concatenate([ball, behind, [[1.5, 1.5, 0.0]]]).astype(np.float32)
    n = len(means)
    g = Gaussians(means, np.full((n, 3), 0.03, np.float32), np.tile([1.0, 0, 0, 0], (n, 1)),
                  np.full(n, 0.9, np.float32), np.zeros((n, 1, 3), np.float32))
    truth = np.arange(n) < 200
    masks = list(target_masks(g, truth, cams, ctx=ctx))
    t = estimate_target(g, cams, masks, ctx=ctx)
    # (the ball's inside is barely seen at 40x30: what matters is that its masks come back)
    assert t is not None and not t.mask[200:].any() and t.mask[:200].mean() > 0.7
    for want, got in zip(masks, target_masks(g, t.mask, cams, ctx=ctx)):
        assert (want & got).sum() >= 0.95 * (want | got).sum()
    assert np.linalg.norm(t.centre - centre) < 0.03 and t.radius < 0.2  # weighted to the seen side
    assert estimate_target(g, cams, [np.zeros((30, 40), bool)] * 6, ctx=ctx) is None
    with pytest.raises(ValueError):
        estimate_target(g, cams, masks[:2], ctx=ctx)


def test_captures(tmp_path):
    import cv2

    img = np.random.default_rng(1).integers(0, 256, (5, 7, 4), np.uint8)
    path = save_png(tmp_path / "a" / "shot.png", img)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(back[..., [2, 1, 0, 3]], img)
    with pytest.raises(ValueError):
        save_png(tmp_path / "bad.png", img.astype(np.float32))
    cams = orbit_cameras(3, 40, 30)
    path = path_through(cams, 4, 20, 10)
    assert len(path) == 9 and all((c.width, c.height) == (20, 10) for c in path)
    assert np.allclose(path[4].center, cams[1].center) and np.allclose(path[-1].R, cams[-1].R)
    rec = PathRecorder(tmp_path / "rec", max_frames=2)
    for cam in path[:3]:
        rec.add(img[..., :3], cam)
    assert rec.full and len(rec.cameras) == 2
    meta = json.loads((rec.close() / "cameras.json").read_text())
    assert [f["file"] for f in meta["frames"]] == ["frame_00000.png", "frame_00001.png"]
    assert np.allclose(meta["frames"][1]["world_to_camera"], path[1].world_to_camera)


def test_results_errors(tmp_path):
    p = tmp_path / "r.json"
    with pytest.raises(InputError, match="cannot read"):
        load_results(p, "x")
    p.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_results(p, "x")
    p.write_text(json.dumps({"schema": "other"}))
    with pytest.raises(InputError, match="not an r360gpu results file"):
        load_results(p, "x")
    p.write_text(json.dumps({"schema": "r360gpu.results/1", "scenes": {"a": {"methods": {"m": {"views": [{}]}}}}}))
    with pytest.raises(InputError, match="view record 0"):
        load_results(p, "a")


def test_view_command(monkeypatch):
    from r360gpu.cli import view

    parser = argparse.ArgumentParser()
    view.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["view", "some/bundle", "--results", "r.json", "--size", "800x600"])
    assert (args.bundle, args.results, args.size, args.func) == ("some/bundle", "r.json", "800x600", view.run)
    monkeypatch.setattr(view.importlib.util, "find_spec", lambda name: None)
    assert view.missing_modules() == list(view.VIEWER_MODULES)
    with pytest.raises(view.ViewerUnavailableError, match=r"pip install -e '\.\[viewer\]'"):
        view.run(args)


def test_launch_parsing():
    from r360gpu.viewer.launch import parse_keys, parse_size

    assert parse_size("640x480") == (640, 480)
    with pytest.raises(InputError):
        parse_size("big")
    with pytest.raises(InputError):
        parse_size("10x10")
    assert parse_keys("Tab x Shift+3 Space Right +") == [
        ("Tab", ()), ("x", ()), ("3", ("Shift",)), (" ", ()), ("ArrowRight", ()), ("+", ())]


def test_no_display_is_a_clear_error(monkeypatch):
    pytest.importorskip("glfw")
    from r360gpu.viewer.launch import WindowUnavailableError, check_display

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    with pytest.raises(WindowUnavailableError, match="xvfb-run"):
        check_display()
