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
from r360gpu.viewer.target import estimate_target, projected_mask


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


def test_target_vote_rejects_what_only_one_view_sees():
    cams = orbit_cameras(6, 40, 30)
    centre = np.array([0.0, 0.0, 0.35])
    ball = centre + np.random.default_rng(0).normal(scale=0.05, size=(200, 3))
    behind = np.array([[0.0, 2.0, 0.35]])  # near the ball from one side only
    means = np.concatenate([ball, behind, [[1.5, 1.5, 0.0]]])
    masks = []
    for cam in cams:
        uv, _ = cam.project(ball)
        m = np.zeros((30, 40), bool)
        m[np.clip(uv[:, 1].astype(int), 0, 29), np.clip(uv[:, 0].astype(int), 0, 39)] = True
        masks.append(m)
    t = estimate_target(means, cams, masks)
    assert t is not None and set(t.indices) == set(range(200))
    assert np.linalg.norm(t.centre - centre) < 0.02 and t.radius < 0.2
    assert estimate_target(means, cams, [np.zeros((30, 40), bool)] * 6) is None
    with pytest.raises(ValueError):
        estimate_target(means, cams, masks[:2])


def test_projected_mask_keeps_the_visible_part():
    alpha = np.array([[1.0, 1.0, 1.0, 0.2]])
    t_depth = np.array([[2.0, 2.0, 2.0, 2.0]])
    pre_depth = np.array([[2.0, 1.0, 0.0, 2.0]])  # same surface / occluder in front / no pre depth
    assert projected_mask(alpha, t_depth, pre_depth).tolist() == [[True, False, True, False]]


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
