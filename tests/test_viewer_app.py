"""The viewer app headless: rendercanvas' offscreen canvas on lavapipe.

Frames are compared with the renderer's own output; keys go through the
same path as in the window (the state machine, then the app's actions).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("rendercanvas")
pytest.importorskip("imgui_bundle")

from r360gpu.bundle import load_bundle  # noqa: E402
from r360gpu.io.masks import load_mask  # noqa: E402
from r360gpu.metrics.geometric import acc_depth_view  # noqa: E402
from r360gpu.metrics.record import ViewRecord  # noqa: E402
from r360gpu.metrics.semantic import SemanticView  # noqa: E402
from r360gpu.render import Renderer  # noqa: E402
from viewer_fixtures import BALL_CENTRE, write_bundle  # noqa: E402
from r360gpu.viewer.app import ViewerApp  # noqa: E402
from r360gpu.viewer.quality import ResolutionPolicy  # noqa: E402
from r360gpu.viewer.results import load_results  # noqa: E402

W, H = 64, 48


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


@pytest.fixture(scope="module")
def bundle(tmp_path_factory, ctx):
    return load_bundle(write_bundle(tmp_path_factory.mktemp("viewer_bundle"), n_views=6, width=W, height=H, ctx=ctx))


@pytest.fixture(scope="module")
def renderers(bundle, ctx):
    from r360gpu.io import load_gaussians

    return {name: Renderer(load_gaussians(spec.path), ctx=ctx) for name, spec in bundle.sources().items()}


def make_app(bundle, ctx, tmp_path, *, size=(W, H), gui=False, results=None, outline=False):
    """An app on an offscreen canvas with a settable clock; the target outline (on by default) off."""
    from rendercanvas.offscreen import OffscreenRenderCanvas

    canvas = OffscreenRenderCanvas(size=size)
    clock = Clock()
    app = ViewerApp(bundle, canvas=canvas, ctx=ctx, results=results, capture_dir=tmp_path, gui=gui, clock=clock,
                    policy=ResolutionPolicy(moving_scale=0.5))
    canvas.request_draw(app.frame)
    if not outline:
        app.key("b")
    assert app.state.overlays.outline == outline
    return app, canvas, clock


def draw(canvas, clock, seconds=1.0):
    """A frame after the camera rested ``seconds`` (full resolution)."""
    clock.t += seconds
    return np.asarray(canvas.draw())


def to8(rgb):
    return np.floor(np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)


def test_frame_is_the_renderers_output(bundle, ctx, renderers, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path)
    img = draw(canvas, clock)
    cam0 = bundle.cameras["view_00"]
    assert img.shape == (H, W, 4) and app.last_scale == 1.0
    assert np.array_equal(img[..., :3], to8(renderers["pre"].render(cam0).rgb))
    app.key("4")  # floaters
    img = draw(canvas, clock)
    assert np.array_equal(img[..., :3], to8(renderers["floaters"].render(cam0).rgb))
    app.key("ArrowRight")
    assert app.current_view() == "view_01"
    img = draw(canvas, clock)
    assert np.array_equal(img[..., :3], to8(renderers["floaters"].render(bundle.cameras["view_01"]).rgb))
    app.close()


def test_side_by_side_and_wipe(bundle, ctx, renderers, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path, size=(2 * W, H))
    assert app.state.name_b == "reference"  # B defaults to what a method is compared against
    app.key("3")
    app.key("$", ("Shift",))  # B = scene 4 (floaters)
    app.key("Tab")
    img = draw(canvas, clock)
    lay, cam = app.last_layout, app.last_camera
    (ax, ay, aw, ah), (bx, by, bw, bh) = lay.rects
    assert (cam.width, cam.height) == (aw, ah) == (bw, bh) == (W, H)
    assert np.array_equal(img[ay:ay + ah, ax:ax + aw, :3], to8(renderers["clean"].render(cam).rgb))
    assert np.array_equal(img[by:by + bh, bx:bx + bw, :3], to8(renderers["floaters"].render(cam).rgb))
    app.key("Tab")  # wipe
    img = draw(canvas, clock)
    lay = app.last_layout
    x0, _, rw, _ = lay.rects[0]
    split = int(lay.wipe_x)
    clean = to8(renderers["clean"].render(app.last_camera).rgb)
    floaters = to8(renderers["floaters"].render(app.last_camera).rgb)
    assert np.array_equal(img[:, x0:split - 2, :3], clean[:, : split - 2 - x0])
    assert np.array_equal(img[:, split + 2:x0 + rw, :3], floaters[:, split + 2 - x0:])
    # Dragging the wipe line moves it.
    app.on_event({"event_type": "pointer_down", "x": lay.wipe_x, "y": 10, "button": 1, "modifiers": ()})
    app.on_event({"event_type": "pointer_move", "x": x0 + 0.25 * rw, "y": 10, "buttons": (1,), "modifiers": ()})
    app.on_event({"event_type": "pointer_up", "x": x0 + 0.25 * rw, "y": 10, "button": 1, "modifiers": ()})
    assert app.state.wipe == pytest.approx(0.25, abs=0.02)
    app.close()


def test_progressive_resolution(bundle, ctx, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path, size=(2 * W, 2 * H))
    draw(canvas, clock)
    full = (app.last_camera.width, app.last_camera.height)
    app.on_event({"event_type": "pointer_down", "x": 50, "y": 40, "button": 1, "modifiers": ()})
    app.on_event({"event_type": "pointer_move", "x": 60, "y": 40, "buttons": (1,), "modifiers": ()})
    app.on_event({"event_type": "pointer_up", "x": 60, "y": 40, "button": 1, "modifiers": ()})
    draw(canvas, clock, 0.0)
    assert app.last_scale == 0.5 and not app.state.on_view
    assert (app.last_camera.width, app.last_camera.height) == (full[0] // 2, full[1] // 2)
    assert app.busy()  # it asks for the refining frame
    draw(canvas, clock, 0.31)
    assert app.last_scale == 1.0 and (app.last_camera.width, app.last_camera.height) == full
    app.close()


def test_held_keys_fly_the_camera(bundle, ctx, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path)
    draw(canvas, clock)
    p0, f0 = app.camera.position.copy(), app.camera.forward
    app.key("g")
    app.key("w")
    draw(canvas, clock, 0.05)
    app.key("w", down=False)
    assert app.camera.mode == "fly"
    step = app.camera.position - p0
    assert np.dot(step, f0) > 0 and np.allclose(np.cross(step, f0), 0, atol=1e-9)
    assert np.linalg.norm(step) == pytest.approx(app.camera.speed * 0.05)
    app.key(" ")  # snap back to the closest evaluation camera
    assert app.current_view() == "view_00"
    app.close()


def test_changed_overlay_and_live_axis_match_the_metric(bundle, ctx, renderers, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path, outline=True)
    for key in ("4", "v", "]", "]", "]", "]"):
        app.key(key)
    img = draw(canvas, clock)
    cam = bundle.cameras["view_00"]
    pre, post = renderers["pre"].render(cam), renderers["floaters"].render(cam)
    mask = load_mask(bundle.masks["view_00"])
    geo = acc_depth_view(pre.depth, post.depth, mask, ctx=ctx)
    magenta = np.all(img[..., :3] == to8(np.array([1.0, 0.1, 0.75])), axis=-1)
    outline = np.all(img[..., :3] == to8(np.array([1.0, 0.86, 0.0])), axis=-1)
    assert geo.changed.any() and outline.any()
    assert np.array_equal(magenta | outline, geo.changed | outline)
    live = app.live["floaters"]
    assert live.mask_kind == "evaluation" and live.acc_depth == geo.acc_depth
    assert app.last_delta["floaters"].split == geo.split
    # Off the evaluation views the live axis uses the estimated target.
    app.camera.orbit(3, 0)
    draw(canvas, clock)  # the move: reduced resolution, no measurement
    assert app.last_scale < 1 and app.live["floaters"].mask_kind == "evaluation"
    draw(canvas, clock)  # rested: measured again
    assert app.live["floaters"].mask_kind == "projected" and app.live["floaters"].n_mask > 0
    app.close()


def test_focus_on_the_target(bundle, ctx, tmp_path):
    app, canvas, clock = make_app(bundle, ctx, tmp_path)
    target = app.ensure_target()
    assert target is not None and np.linalg.norm(target.centre - BALL_CENTRE) < 0.1
    assert 0.15 < target.radius < 0.45
    app.key("f")
    assert np.allclose(app.camera.pivot, target.centre)
    cam = app.camera.render_camera(W, H)
    uv, z = cam.project(target.centre[None])
    assert np.allclose(uv[0], (W / 2, H / 2)) and z[0] > 0
    app.close()


def test_screenshot_and_recording(bundle, ctx, tmp_path, capsys):
    from r360gpu.viewer.capture import path_through

    app, canvas, clock = make_app(bundle, ctx, tmp_path)
    img = draw(canvas, clock)
    shot = tmp_path / "shot.png"
    app.request_screenshot("view", shot)
    draw(canvas, clock)
    assert f"screenshot: {shot.resolve()}" in capsys.readouterr().out  # where it went, on the terminal
    import cv2

    saved = cv2.imread(str(shot), cv2.IMREAD_UNCHANGED)[..., [2, 1, 0]]
    assert np.array_equal(saved, img[..., :3])
    app.key("k")
    for cam in path_through([bundle.cameras["view_00"], bundle.cameras["view_01"]], 3, W, H):
        app.camera.set_camera(cam)
        draw(canvas, clock, 0.05)
    app.key("k")
    folder = next(tmp_path.glob("record_*"))
    frames = sorted(folder.glob("frame_*.png"))
    meta = json.loads((folder / "cameras.json").read_text())
    assert len(frames) == len(meta["frames"]) == 4  # one frame per distinct camera
    # A fly-through of the evaluation path records itself and stops at its end.
    app.fly_evaluation_path(steps=2)
    frames_drawn = 0
    while app.recorder is not None and frames_drawn < 50:
        draw(canvas, clock, 0.01)
        frames_drawn += 1
    flights = sorted(tmp_path.glob("record_*"))
    assert len(flights) == 2 and not app.state.recording
    meta = json.loads((flights[-1] / "cameras.json").read_text())
    assert len(meta["frames"]) == 2 * (len(bundle.views) - 1) + 1
    assert np.allclose(meta["frames"][2]["world_to_camera"], bundle.cameras["view_01"].world_to_camera)
    app.close()


def test_results_in_the_app(bundle, ctx, tmp_path):
    views = []
    for i, v in enumerate(bundle.views):
        sem = SemanticView(0.8, 0.1 * i, False, 100, 90, 10 * i, 80, 5 * i, 1, 1, probe="p")
        views.append(ViewRecord.build(v, "tiny", "floaters", semantic=[sem],
                                      geometric={"acc_depth": 0.1 * i}).to_dict())
    doc = {"schema": "r360gpu.results/1", "probes": {"semantic": [{"name": "p"}], "structural": []},
           "scenes": {"tiny": {"prompt": "ball", "methods": {"floaters": {"axes": {"rqs": 0.5}, "views": views}}}}}
    path = tmp_path / "results.json"
    path.write_text(json.dumps(doc))
    res = load_results(path, "tiny")
    m = res.methods["floaters"]
    assert m.series("s_geo", bundle.views) == pytest.approx([0.1 * i for i in range(6)])
    assert m.series("s_sem", bundle.views)[:4] == [1.0, 1.0, 1.0, 0.0]  # IoU_post >= 0.3 is detected
    assert np.isnan(m.series("s_str", bundle.views)).all()
    # worst view: lowest mean of (s_sem, s_geo): view 3, s_sem 0 and s_geo 0.3
    assert m.worst_view(bundle.views) == bundle.views[3] and m.worst_view([]) is None
    assert res.probe_cache == tmp_path / ".r360cache" / "probes"
    with pytest.raises(Exception, match="no scene 'other'"):
        load_results(path, "other")
    # With panels on the offscreen canvas: the UI draws over the view.
    app, canvas, clock = make_app(bundle, ctx, tmp_path, size=(640, 400), gui=True, results=res)
    app.key("4")
    assert app.state.name_a == "floaters"
    app.key("j")  # J: the camera jumps to floaters' worst view
    assert app.current_view() == bundle.views[3]
    with_ui = draw(canvas, clock)
    app.key("i")
    without = draw(canvas, clock)
    differs = np.any(with_ui != without, axis=-1)
    assert differs[:, :300].mean() > 0.5 and differs[:, 300:].any()
    # Every panel branch draws: help, wipe slider, manual ranges, overlays with their read-outs.
    for key in ("i", "h", "Tab", "Tab", "z", "x", "n"):
        app.key(key)
    app.set_state(app.state.with_overlays(depth_auto=False, delta_auto=False, depth_range=(1.0, 4.0)))
    app.camera.orbit(5, 0)
    draw(canvas, clock, 0.0)
    busy = draw(canvas, clock)
    assert app.live and not app.live_stale and app.state.compare == "wipe" and busy.std() > 10
    app.close()


def test_renders_source_shows_at_evaluation_views_only(tmp_path, ctx):
    import cv2

    b = load_bundle(write_bundle(tmp_path / "b", n_views=4, width=W, height=H, ctx=ctx, renders=True))
    app, canvas, clock = make_app(b, ctx, tmp_path, size=(2 * W, 2 * H))
    assert app.layers["painted"].kind == "renders"
    app.key("5")
    app.key("x")
    img = draw(canvas, clock)
    # On a view the pictures take the renders' own size and aspect; |dD| against pre works there.
    assert (app.last_camera.width, app.last_camera.height) == (W, H)
    assert "painted" in app.last_delta
    app.key("x")
    img = draw(canvas, clock)
    x, y, w, h = app.last_layout.rects[0]
    png = cv2.imread(str(b.root / "painted" / "rgb" / "view_00.png"))[..., ::-1]
    small = cv2.resize(img[y:y + h, x:x + w, :3], (W, H), interpolation=cv2.INTER_AREA)
    assert np.abs(small.astype(int) - png).mean() < 2.0
    # Off the evaluation views a renders source has nothing to show: letterbox only.
    app.camera.orbit(20, 0)
    draw(canvas, clock)
    img = draw(canvas, clock)
    assert app.current_view() is None
    assert len(np.unique(img[..., :3].reshape(-1, 3), axis=0)) == 1
    app.close()


def test_cached_probe_masks_are_drawn(bundle, ctx, tmp_path):
    from r360gpu.probes.base import MaskSet
    from r360gpu.probes.cache import ProbeCache, cache_key
    from r360gpu.render.sources import open_source
    from r360gpu.viewer.results import SceneResults

    desc = {"name": "toy-sam", "kind": "structural", "models": {}, "params": {"k": 1}}
    src = open_source(bundle.methods["floaters"], ctx=ctx)
    rgb = src.images("view_00", bundle.cameras["view_00"]).rgb
    masks = np.zeros((2, H, W), bool)
    masks[0, :10, :20] = True
    masks[1, 30:, 40:] = True
    cache = ProbeCache(tmp_path / ".r360cache" / "probes")
    cache.store("toy-sam", cache_key(rgb, "toy-sam", desc, None), MaskSet(masks, None, "toy-sam"))
    res = SceneResults(path=tmp_path / "results.json", scene="tiny", methods={},
                       probes={"semantic": [], "structural": [desc]}, prompt="ball")
    app, canvas, clock = make_app(bundle, ctx, tmp_path, results=res)
    app.key("4")
    plain = draw(canvas, clock)
    app.key("n")
    tinted = draw(canvas, clock)
    assert [p.probe for p in app.probe_found] == ["toy-sam"]
    changed = np.any(plain != tinted, axis=-1)
    assert changed[:10, :20].mean() > 0.9 and changed[30:, 40:].mean() > 0.9
    assert not changed[15:25, :].any()
    app.key("ArrowRight")  # nothing cached for view_01
    draw(canvas, clock)
    assert app.probe_found == []
    app.close()


def test_renders_only_bundle_without_cameras(tmp_path, ctx):
    """A bundle of renderings alone: no free camera, stepping through the views still works."""
    import shutil

    root = write_bundle(tmp_path / "b", n_views=3, width=W, height=H, ctx=ctx, renders=True)
    shutil.copytree(root / "painted", root / "pre_renders")
    (root / "scene.toml").write_text('name = "r"\nprompt = "ball"\nmasks = "masks"\n[pre]\nrenders = "pre_renders"\n'
                                     '[methods.painted]\nrenders = "painted"\n', encoding="utf-8")
    b = load_bundle(root)
    assert b.cameras is None
    app, canvas, clock = make_app(b, ctx, tmp_path)
    assert not app.can_move
    app.key("2")
    app.key("ArrowRight")
    app.on_event({"event_type": "pointer_down", "x": 5, "y": 5, "button": 1, "modifiers": ()})
    app.on_event({"event_type": "pointer_move", "x": 30, "y": 5, "buttons": (1,), "modifiers": ()})
    img = draw(canvas, clock)
    assert app.current_view() == "view_01" and app.live["painted"].acc_depth == 0.0
    png = cv2_rgb(root / "painted" / "rgb" / "view_01.png")
    assert np.array_equal(img[..., :3], png)
    app.close()


def cv2_rgb(path):
    import cv2

    return cv2.imread(str(path))[..., ::-1]


def test_command_line_start(bundle, tmp_path):
    import argparse

    from rendercanvas.offscreen import OffscreenRenderCanvas

    from r360gpu.errors import InputError
    from r360gpu.viewer.launch import add_arguments, open_viewer

    p = argparse.ArgumentParser()
    add_arguments(p)
    args = p.parse_args([str(bundle.root), "--view", "view_02", "--keys", "4 Shift+3 Tab z",
                         "--capture-dir", str(tmp_path)])
    app = open_viewer(args, OffscreenRenderCanvas(size=(W, H)), gui=False)
    s = app.state
    assert app.current_view() == "view_02" and (s.name_a, s.name_b, s.compare) == ("floaters", "clean", "side")
    assert s.overlays.depth and s.held == frozenset()
    app.close()
    with pytest.raises(InputError, match="not an evaluation view"):
        open_viewer(p.parse_args([str(bundle.root), "--view", "nope"]), OffscreenRenderCanvas(size=(W, H)))


def test_residual_highlight_toggles_with_one_key(bundle, ctx, renderers, tmp_path):
    """Key O: the shown method drawn with its Gaussians coloured by the results file's residuals PLY;
    again: its own colours.  A scene without residuals stays as it is, with a message."""
    from r360gpu.io import load_gaussians
    from r360gpu.lift.residuals import write_residual_ply
    from r360gpu.viewer.residuals import highlight_colours, highlighted

    g = load_gaussians(bundle.methods["floaters"].path)
    r = np.zeros(g.n)
    r[-(g.n // 10):] = np.linspace(0.2, 1.0, g.n // 10)  # the last tenth (the junk) carries the evidence
    write_residual_ply(tmp_path / "residuals" / "tiny" / "floaters.ply", g, r)
    doc = {"schema": "r360gpu.results/1", "probes": {"semantic": [], "structural": []},
           "scenes": {"tiny": {"prompt": "ball", "methods": {},
                               "residuals": {"floaters": {"file": "residuals/tiny/floaters.ply"}}}}}
    (tmp_path / "results.json").write_text(json.dumps(doc))
    res = load_results(tmp_path / "results.json", "tiny")
    assert res.residuals == {"floaters": tmp_path / "residuals" / "tiny" / "floaters.ply"}
    app, canvas, clock = make_app(bundle, ctx, tmp_path, results=res)
    cam0 = bundle.cameras["view_00"]
    app.key("4")  # floaters
    plain = draw(canvas, clock)
    assert np.array_equal(plain[..., :3], to8(renderers["floaters"].render(cam0).rgb))
    app.key("o")
    assert app.state.overlays.residuals
    lit = draw(canvas, clock)
    want = Renderer(highlighted(g, r.astype(np.float32)), ctx=ctx).render(cam0).rgb
    assert np.array_equal(lit[..., :3], to8(want)) and not np.array_equal(lit, plain)
    app.key("o")
    assert np.array_equal(draw(canvas, clock), plain)
    # pre has no residuals: toggling says so and draws pre as it is
    app.key("1")
    app.key("o")
    assert any("no residuals for pre" in m for _, m in app.messages)
    assert np.array_equal(draw(canvas, clock)[..., :3], to8(renderers["pre"].render(cam0).rgb))
    app.close()
    # the colours: residual 0 is the Gaussian's grey, 1 the brightest heat; in [0, 1] throughout
    c = highlight_colours(np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2, 0.4, 0.6]]), np.array([0.0, 1.0, np.nan]))
    assert np.allclose(c[0], c[0][0]) and c[1][0] > 0.9 and c[1][2] < c[1][0] and np.allclose(c[2], c[2][0])
    assert (c >= 0).all() and (c <= 1).all()
