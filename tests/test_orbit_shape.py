"""The orbit's shape (radius, elevations, azimuths as options; poses inside the capture's bounds) and
the reasons a pose is dropped: "never seen" (that side of the target no given view saw) apart from
"target occluded"."""
from __future__ import annotations

import numpy as np
import pytest

from r360gpu.errors import InputError
from r360gpu.io.camera import Camera
from r360gpu.lift.orbit import (BOUNDS_MARGIN, NEVER_SEEN, OCCLUDED, capture_reach, capture_up, captured,
                                keep_pose, orbit_cameras, seen_share)


def _look_at(eye, centre, name, w=64, h=48, f=60.0):
    fwd = np.asarray(centre, float) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    c2w = np.eye(4)
    c2w[:3, :3] = np.stack([right, np.cross(fwd, right), fwd], 1)
    c2w[:3, 3] = eye
    return Camera.from_camera_to_world(c2w, f, f, w / 2, h / 2, w, h, name)


def _ring(centre, n=8, r=3.0, wobble=0.0):
    """A capture all around ``centre`` (z up), at elevations 10..30 degrees."""
    cams = []
    for i in range(n):
        az, el = 2 * np.pi * i / n, np.deg2rad(10 + 20 * i / (n - 1))
        d = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        cams.append(_look_at(centre + (r + wobble * i) * d, centre, f"c{i}"))
    return cams


def _elevations(cams, centre, up):
    off = np.array([c.center - centre for c in cams])
    return np.degrees(np.arcsin(off @ up / np.linalg.norm(off, axis=1)))


def test_radius_elevation_and_azimuth_are_options():
    centre = np.array([1.0, 2.0, 0.5])
    cams = _ring(centre)
    up = capture_up(cams)
    orbit = orbit_cameras(centre, cams, 24, radius=0.5, elevation=(-10, 40), azimuth=(90, 180))
    dist = np.array([np.linalg.norm(c.center - centre) for c in orbit])
    assert np.allclose(dist, 1.5)  # half the capture's median distance: inside its bounds, not capped
    el = _elevations(orbit, centre, up)
    assert el.min() >= -10 - 1e-6 and el.max() <= 40 + 1e-6 and el.max() - el.min() > 40
    off = np.array([c.center - centre for c in orbit])
    az = np.degrees(np.arctan2(off[:, 1], off[:, 0])) % 360  # the first capture camera sits at azimuth 0
    assert az.min() >= 90 - 1e-6 and az.max() <= 180 + 1e-6
    for c in orbit:  # every pose still looks at the target
        uv, z = c.project(centre[None])
        assert np.allclose(uv[0], (c.cx, c.cy)) and z[0] > 0
    # the defaults are the capture's own band, all the way round
    default = orbit_cameras(centre, cams, 12)
    dist = np.array([np.linalg.norm(c.center - centre) for c in default])
    assert np.all(dist <= 3.0 + 1e-9) and np.all(dist > 0.9 * 3.0)  # the ring's own radius, a few pulled in
    el = _elevations(default, centre, up)
    assert el.min() >= 10 - 1e-6 and el.max() <= 30 + 1e-6


def test_poses_stay_inside_the_capture_bounds():
    centre = np.zeros(3)
    cams = _ring(centre, n=8, r=3.0, wobble=0.1)  # a capture all around: its extent bounds the room
    up = capture_up(cams)
    reach = capture_reach(centre, cams, up)
    assert reach is not None and np.allclose(reach @ up, 0)
    orbit = orbit_cameras(centre, cams, 16, radius=3.0)  # a radius of ~9: far outside the room
    for c in orbit:
        off = c.center - centre
        h = off - (off @ up) * up
        u = h / np.linalg.norm(h)
        assert np.linalg.norm(h) <= (1 + BOUNDS_MARGIN) * (reach @ u).max() + 1e-9  # not past the capture
        assert 0 < np.linalg.norm(off) < 9.0
        uv, z = c.project(centre[None])
        assert np.allclose(uv[0], (c.cx, c.cy)) and z[0] > 0
    # within the capture's extent nothing moves
    assert np.allclose([np.linalg.norm(c.center - centre) for c in orbit_cameras(centre, cams, 16, radius=0.5)],
                       0.5 * np.median([np.linalg.norm(c.center - centre) for c in cams]))
    # a capture from one side says nothing of the room behind the target: nothing is capped
    side = [c for c in cams if c.center[0] > 0.5]
    assert capture_reach(centre, side, up) is None
    far = orbit_cameras(centre, side, 8, radius=3.0)
    assert np.allclose([np.linalg.norm(c.center - centre) for c in far],
                       3.0 * np.median([np.linalg.norm(c.center - centre) for c in side]))


def test_never_seen_is_kept_apart_from_occluded():
    alpha, depth = np.ones((4, 4)), np.full((4, 4), 5.0)
    sil = np.zeros((4, 4), bool)
    sil[1:3, 1:3] = True
    hidden = np.zeros((4, 4), bool)
    assert keep_pose(alpha, depth, hidden, sil, 5.0) == OCCLUDED  # not known: as before
    assert keep_pose(alpha, depth, hidden, sil, 5.0, seen_share=0.9) == OCCLUDED
    assert keep_pose(alpha, depth, hidden, sil, 5.0, seen_share=0.1) == NEVER_SEEN
    assert keep_pose(alpha, depth, sil, sil, 5.0, seen_share=0.0) is None  # visible: scored whatever was seen
    assert seen_share(np.array([1.0, 3.0]), np.array([True, False])) == pytest.approx(0.25)
    assert seen_share(np.zeros(2), np.array([True, False])) is None


def _layer(x, n=12, spacing=0.03, scale=0.03):
    from r360gpu.io import Gaussians

    yy, zz = np.meshgrid(np.arange(n) - (n - 1) / 2, np.arange(n) - (n - 1) / 2)
    k = n * n
    means = np.stack([np.full(k, x), yy.ravel() * spacing, zz.ravel() * spacing], 1)
    quats = np.tile([1.0, 0, 0, 0], (k, 1))
    sh = np.full((k, 1, 3), 0.5)
    return Gaussians(means, np.full((k, 3), scale), quats, np.full(k, 0.99), sh)


def test_captured_tells_the_side_the_capture_saw(ctx):
    from r360gpu.io import Gaussians
    from r360gpu.lift.device import MaskLifter

    front, back = _layer(0.05, n=28, spacing=0.015), _layer(-0.05)  # a dense front: opaque from the capture
    g = Gaussians.concat([front, back])
    target = np.ones(g.n, bool)
    capture = [_look_at(np.array([2.0, 0.2 * i, 0.1]), np.zeros(3), f"c{i}") for i in range(3)]
    seen = captured(g, target, capture, ctx=ctx)
    assert seen[:front.n].all() and not seen[front.n:].any()  # the opaque front hides the back
    behind = _look_at(np.array([-2.0, 0.0, 0.1]), np.zeros(3), "b")
    lifter = MaskLifter(g, ctx=ctx)
    try:
        shares = []
        for cam in (capture[1], behind):
            lifter.reset()
            lifter.add_view(cam, np.ones((cam.height, cam.width), np.float32))
            shares.append(seen_share(lifter.weights()[0], seen))
    finally:
        lifter.release()
    assert shares[0] > 0.9 and shares[1] < 0.5  # from behind: mostly the side the capture never saw


def test_the_capture_weights_summed_in_the_lifts_passes_are_the_separate_lifters(ctx):
    """lift_target(capture=...) sums the whole weights in the masks' own passes (and alone at a
    capture camera with no mask): exactly the integers `captured` gets from a lifter of its own, and
    the lift itself is unchanged."""
    from r360gpu.io import Gaussians
    from r360gpu.lift.device import MaskLifter
    from r360gpu.lift.target import lift_target

    g = Gaussians.concat([_layer(0.05, n=20, spacing=0.02), _layer(-0.05)])
    target = np.zeros(g.n, bool)
    target[::3] = True
    capture = [_look_at(np.array([2.0, 0.3 * i - 0.3, 0.1 * i]), np.zeros(3), f"c{i}") for i in range(3)]
    capture.append(_look_at(np.array([-2.0, 0.1, 0.2]), np.zeros(3), "behind"))
    rng = np.random.default_rng(7)
    masked = capture[:3]  # the one behind has no mask: its weights go to the capture's sums only
    masks = [rng.random((c.height, c.width)) < 0.4 for c in masked]
    plain = lift_target(g, masked, masks, ctx=ctx)
    both = lift_target(g, masked, masks, ctx=ctx, capture=capture)
    assert plain.w_capture is None
    assert np.array_equal(both.w_in, plain.w_in) and np.array_equal(both.w_out, plain.w_out)
    assert np.array_equal(both.target, plain.target)
    lifter = MaskLifter(g, ctx=ctx)
    try:
        lifter.reset()
        for cam in capture:
            lifter.add_view(cam, np.ones((cam.height, cam.width), np.float32))
        alone = lifter.weights()[0]
    finally:
        lifter.release()
    assert np.array_equal(both.w_capture, alone)
    assert (alone > 0).sum() > g.n // 2  # the capture sees most Gaussians: the comparison is not of zeros
    for cams, lifted in ((capture, both), (masked, lift_target(g, masked, masks, ctx=ctx, capture=masked))):
        seen = captured(g, target, cams, ctx=ctx)
        assert np.array_equal(captured(g, target, cams, weights=lifted.w_capture), seen)
    assert not seen.all()  # from the front only, the back layer is hidden: both verdicts occur


def test_options_and_flags_of_the_orbit_shape():
    from r360gpu.pipeline import EvaluateOptions

    o = EvaluateOptions(orbit=4, orbit_radius=0.8, orbit_elevation=(0, 45), orbit_azimuth=(-90, 90))
    assert o.orbit_shape() == {"radius": 0.8, "elevation": (0.0, 45.0), "azimuth": (-90.0, 90.0)}
    assert "orbit_radius" not in o.scoring_key()  # the poses themselves are in the orbit's cache key
    for bad in (dict(orbit_radius=0), dict(orbit_radius="1"), dict(orbit_radius=float("nan")),
                dict(orbit_elevation=(10, 100)), dict(orbit_elevation=(40, 10)), dict(orbit_elevation=5),
                dict(orbit_azimuth=(10, 10)), dict(orbit_azimuth=(0, 400)), dict(orbit_azimuth=("0", 90))):
        with pytest.raises(InputError, match="orbit_"):
            EvaluateOptions(**bad)
    from r360gpu.cli import build_parser
    from r360gpu.cli.score import options_from_args

    args = build_parser().parse_args(["score", "x", "--out", "o", "--orbit", "4", "--orbit-radius", "0.7",
                                      "--orbit-elevation", "5", "25", "--orbit-azimuth", "0", "180"])
    assert options_from_args(args).orbit_shape() == {"radius": 0.7, "elevation": (5.0, 25.0),
                                                     "azimuth": (0.0, 180.0)}
