"""The viewer in a real glfw window under Xvfb, on the synthetic benchmark.

Starts a private Xvfb server, runs ``python -m viewer`` on a small synthetic
bundle with ``--screenshot``, and checks the picture: not blank, the scene
drawn, the imgui panels drawn.  The screenshot is kept as a CI artifact at
``test-output/viewer/screenshot.png`` under the repository root.
Skipped only when Xvfb is not installed (Debian: ``apt-get install xvfb``).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("glfw")
pytest.importorskip("imgui_bundle")
pytest.importorskip("rendercanvas")

ROOT = Path(__file__).resolve().parents[1]
ARTIFACT = ROOT / "test-output" / "viewer" / "screenshot.png"
SIZE = (900, 560)
# imgui's dark style draws the focused window's title bar in this opaque colour.
TITLE_BG_ACTIVE = (41, 74, 122)


@pytest.fixture(scope="module")
def display():
    """A private Xvfb display number; the server is stopped afterwards."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        pytest.skip("Xvfb is not installed (Debian/Ubuntu: apt-get install -y xvfb)")
    r, w = os.pipe()
    proc = subprocess.Popen([xvfb, "-displayfd", str(w), "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    os.close(w)
    try:
        with os.fdopen(r) as f:
            number = f.readline().strip()
        if not number:
            err = proc.stderr.read().decode(errors="replace") if proc.poll() is not None else ""
            pytest.fail(f"Xvfb did not start: {err}")
        yield f":{number}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_window_draws_scene_and_panels(display, tmp_path, ctx):
    import cv2

    from r360gpu.synthetic import generate_benchmark

    bundle = generate_benchmark(tmp_path / "bench", seed=0, n_views=6, width=160, height=120, scenes=("room",),
                                detail=0.2, ctx=ctx)[0]
    if ARTIFACT.exists():
        ARTIFACT.unlink()
    env = dict(os.environ, DISPLAY=display)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    cmd = [sys.executable, "-m", "r360gpu.viewer", str(bundle), "--size", f"{SIZE[0]}x{SIZE[1]}",
           "--screenshot", str(ARTIFACT), "--keys", "4 Shift+1 Tab v"]
    run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"viewer failed:\n{run.stdout}\n{run.stderr}"
    assert ARTIFACT.is_file(), "no screenshot written"
    img = cv2.imread(str(ARTIFACT), cv2.IMREAD_COLOR)[..., ::-1].astype(int)
    assert img.shape[:2] == (SIZE[1], SIZE[0])
    # Not blank: many colours and real contrast.
    assert img.std() > 20
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 500
    # The scene: right of the left panel, above the Metrics dock (bottom: side by side of 4:3
    # pictures leaves more room there), a rendering, not the letterbox.
    middle = img[20: SIZE[1] // 2, 360: SIZE[0] - 20]
    assert len(np.unique(middle.reshape(-1, 3), axis=0)) > 200
    # The panels: the left one is dark with light text, and a focused title bar is drawn.
    left = img[40: SIZE[1] - 40, 12: 320]
    assert (left.max(axis=-1) < 90).mean() > 0.4
    assert (left.min(axis=-1) > 200).sum() > 300
    title = np.all(np.abs(img - np.array(TITLE_BG_ACTIVE)) <= 2, axis=-1)
    assert title.sum() > 500


# -- the viewer: panels beside the panes, labels, renders-only explanation, Esc / Q ----------

PANES_ARTIFACT = ROOT / "test-output" / "viewer" / "side_by_side.png"
HIDDEN_ARTIFACT = ROOT / "test-output" / "viewer" / "renders_only_hidden_panels.png"
#: Colour of the explanation drawn on a pane without a picture (viewer.panels.MISSING_FG).
MISSING_RGB = (255, 217, 115)


def _run_viewer(display, bundle, keys: str, shot: Path | None, tmp_path: Path, *, size=SIZE, results=None):
    env = dict(os.environ, DISPLAY=display)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    cmd = [sys.executable, "-m", "r360gpu.viewer", str(bundle), "--size", f"{size[0]}x{size[1]}", "--keys", keys,
           "--capture-dir", str(tmp_path / "captures")]
    if shot is not None:
        cmd += ["--screenshot", str(shot)]
    if results is not None:
        cmd += ["--results", str(results)]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


def test_panels_never_cover_the_panes(display, tmp_path, ctx):
    """Side by side: the view capture (pictures only) appears unchanged in the window, apart from
    the two small A / B labels: no panel covers any part of either pane."""
    import cv2

    from r360gpu.synthetic import generate_benchmark

    bundle = generate_benchmark(tmp_path / "bench", seed=0, n_views=6, width=160, height=120, scenes=("room",),
                                detail=0.2, ctx=ctx)[0]
    size = (1280, 720)
    run = _run_viewer(display, bundle, "4 Tab p", PANES_ARTIFACT, tmp_path, size=size)
    assert run.returncode == 0, f"viewer failed:\n{run.stdout}\n{run.stderr}"
    window = cv2.imread(str(PANES_ARTIFACT), cv2.IMREAD_COLOR)
    views = list((tmp_path / "captures").glob("*.png"))
    assert len(views) == 1, views
    view = cv2.imread(str(views[0]), cv2.IMREAD_COLOR)
    assert view.shape[1] > 2 * view.shape[0] * 0.9  # two panes side by side
    res = cv2.matchTemplate(window, view, cv2.TM_SQDIFF)
    _, _, (x, y), _ = cv2.minMaxLoc(res)
    crop = window[y:y + view.shape[0], x:x + view.shape[1]]
    same = np.all(crop == view, axis=-1)
    # Only the label boxes (top-left of each pane) may differ.
    assert same.mean() > 0.97, same.mean()
    diff_rows, diff_cols = np.nonzero(~same)
    assert diff_rows.size == 0 or diff_rows.max() < 40
    # The Metrics dock is drawn (beside or below the panes, not over them).
    assert x >= 300 and (y + view.shape[0] < size[1] - 200 or x + view.shape[1] < size[0] - 300)


def test_renders_only_pane_explains_itself_with_panels_hidden(display, tmp_path, ctx):
    import cv2

    from viewer_fixtures import write_bundle

    bundle = write_bundle(tmp_path / "b", n_views=4, width=96, height=72, ctx=ctx, renders=True)
    # A = painted (renders only), B = reference, side by side, camera reset (off the evaluation views),
    # panels hidden.
    run = _run_viewer(display, bundle, "5 Tab r i", HIDDEN_ARTIFACT, tmp_path)
    assert run.returncode == 0, f"viewer failed:\n{run.stdout}\n{run.stderr}"
    img = cv2.imread(str(HIDDEN_ARTIFACT), cv2.IMREAD_COLOR)[..., ::-1].astype(int)
    left, right = img[:, : SIZE[0] // 2], img[:, SIZE[0] // 2:]
    # the explanation on the left (A) pane, in its colour; the right pane shows the reference
    text = np.all(np.abs(left - np.array(MISSING_RGB)) <= 40, axis=-1)
    assert text.sum() > 150
    assert not np.all(np.abs(right - np.array(MISSING_RGB)) <= 40, axis=-1).any()
    assert len(np.unique(right.reshape(-1, 3), axis=0)) > 200
    # labels: white text on a dark box at the top left of each pane, with no panel drawn
    for half in (left, right):
        top = half[: SIZE[1] // 2]
        assert (top.min(axis=-1) > 230).sum() > 30
    title = np.all(np.abs(img - np.array(TITLE_BG_ACTIVE)) <= 2, axis=-1)
    assert title.sum() < 50  # no imgui window


@pytest.mark.parametrize("key", ["Escape", "q"])
def test_escape_and_q_close_the_window(display, tmp_path, ctx, key):
    from viewer_fixtures import write_bundle

    bundle = write_bundle(tmp_path / "b", n_views=2, width=64, height=48, ctx=ctx)
    run = _run_viewer(display, bundle, f"Tab {key}", None, tmp_path, size=(400, 300))
    assert run.returncode == 0, f"viewer failed:\n{run.stdout}\n{run.stderr}"
