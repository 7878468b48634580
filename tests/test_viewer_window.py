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
    cmd = [sys.executable, "-m", "viewer", str(bundle), "--size", f"{SIZE[0]}x{SIZE[1]}",
           "--screenshot", str(ARTIFACT), "--keys", "4 Shift+1 Tab v"]
    run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"viewer failed:\n{run.stdout}\n{run.stderr}"
    assert ARTIFACT.is_file(), "no screenshot written"
    img = cv2.imread(str(ARTIFACT), cv2.IMREAD_COLOR)[..., ::-1].astype(int)
    assert img.shape[:2] == (SIZE[1], SIZE[0])
    # Not blank: many colours and real contrast.
    assert img.std() > 20
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 500
    # The scene: the middle of the window (between the panels) is a rendering, not the letterbox.
    middle = img[SIZE[1] // 4: 3 * SIZE[1] // 4, 360: SIZE[0] - 400]
    assert len(np.unique(middle.reshape(-1, 3), axis=0)) > 200
    # The panels: the left one is dark with light text, and a focused title bar is drawn.
    left = img[40: SIZE[1] - 40, 12: 320]
    assert (left.max(axis=-1) < 90).mean() > 0.4
    assert (left.min(axis=-1) > 200).sum() > 300
    title = np.all(np.abs(img - np.array(TITLE_BG_ACTIVE)) <= 2, axis=-1)
    assert title.sum() > 500
