"""Command-line options and start-up of the desktop viewer (glfw window).

Shared by ``python -m viewer`` and ``r360gpu view``.  Besides the bundle and
the results file, a few options script the start (``--view``, ``--keys``)
and ``--screenshot PATH`` saves the window once the first full-resolution
frame is drawn and quits (documentation pictures, CI).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from r360gpu.errors import R360Error

#: Frames drawn before --screenshot fires (imgui sizes its windows over the first frames).
SETTLE_FRAMES = 4
#: --screenshot fires after this many frames even if the view never settles.
MAX_FRAMES_BEFORE_SCREENSHOT = 300


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bundle", help="scene bundle folder (scene.toml) or a Remove360 evaluation folder")
    p.add_argument("--results", metavar="PATH", default=None,
                   help="results.json of 'r360gpu score' for the per-view axes, RQS and cached probe masks")
    p.add_argument("--size", default="1280x720", metavar="WxH", help="window size in pixels (default 1280x720)")
    p.add_argument("--adapter", default=None, help="GPU adapter: auto, gpu, cpu, or part of its name")
    p.add_argument("--view", default=None, metavar="NAME", help="start on this evaluation view")
    p.add_argument("--keys", default="", metavar="KEYS",
                   help="keys pressed at start, space separated, e.g. \"Tab x Shift+3\" (see the key bindings)")
    p.add_argument("--capture-dir", default=None, metavar="DIR",
                   help="folder of screenshots and recordings (default ./r360gpu-captures)")
    p.add_argument("--screenshot", default=None, metavar="PNG",
                   help="save the window (with panels) once the first full-resolution frame is drawn, then quit")
    p.add_argument("--max-fps", type=float, default=60.0, help="frame-rate cap (default 60)")


def parse_size(text: str) -> tuple[int, int]:
    from r360gpu.errors import InputError

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must look like 1280x720, got {text!r}") from None
    if w < 64 or h < 64:
        raise InputError(f"--size must be at least 64x64, got {text!r}")
    return w, h


def parse_keys(text: str) -> list[tuple[str, tuple[str, ...]]]:
    """"Tab x Shift+3" -> [("Tab", ()), ("x", ()), ("3", ("Shift",))].

    "Space" is the space bar, "Plus" the + key, "Left" / "Right" the arrow keys.
    """
    out = []
    for token in text.split():
        *mods, key = token.split("+") if len(token) > 1 else [token]
        key = {"Space": " ", "Plus": "+", "Left": "ArrowLeft", "Right": "ArrowRight"}.get(key, key)
        out.append((key, tuple(mods)))
    return out


class WindowUnavailableError(R360Error):
    """No window can be opened (no display, or GLFW cannot start)."""


def load_inputs(args):
    """(bundle, results or None, GpuContext) of the command line; input errors come before any window."""
    from r360gpu.bundle import load_bundle
    from r360gpu.errors import InputError
    from r360gpu.gpu import get_context

    from .results import load_results

    bundle = load_bundle(args.bundle)
    if args.view is not None and args.view not in bundle.views:
        views = bundle.views
        raise InputError(f"--view {args.view!r} is not an evaluation view of {bundle.root} "
                         f"(views: {', '.join(views[:8])}{' ...' if len(views) > 8 else ''})")
    results = load_results(args.results, bundle.name) if args.results else None
    return bundle, results, get_context(args.adapter)


def check_display() -> None:
    """Start GLFW, or raise :class:`WindowUnavailableError` saying why (GLFW would abort later)."""
    import glfw

    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) and sys.platform.startswith("linux"):
        raise WindowUnavailableError("no display to open the viewer window on (DISPLAY / WAYLAND_DISPLAY unset); "
                                     "on a headless machine run it under Xvfb: xvfb-run -a r360gpu view ...")
    reporting = glfw.ERROR_REPORTING
    glfw.ERROR_REPORTING = "ignore"
    try:
        ok = glfw.init()
    finally:
        glfw.ERROR_REPORTING = reporting
    if not ok:
        desc = glfw.get_error()[1] if hasattr(glfw, "get_error") else b""
        text = desc.decode(errors="replace") if isinstance(desc, bytes) else str(desc or "")
        raise WindowUnavailableError(f"GLFW cannot open a window{': ' + text if text else ''}")


def open_viewer(args, canvas, *, gui: bool = True, inputs=None):
    """Build a :class:`r360gpu.viewer.app.ViewerApp` on ``canvas`` from the command line (``inputs``: the
    result of :func:`load_inputs`, loaded here when None), at ``--view`` with ``--keys`` pressed."""
    from .app import ViewerApp

    bundle, results, ctx = inputs if inputs is not None else load_inputs(args)
    app = ViewerApp(bundle, canvas=canvas, results=results, ctx=ctx, capture_dir=args.capture_dir, gui=gui)
    if args.view is not None:
        app.jump_to_view(app.views.index(args.view))
    for key, mods in parse_keys(args.keys):
        app.key(key, mods, down=True)
        app.key(key, mods, down=False)
    return app


def run(args) -> int:
    """Open the window and run until it is closed (or --screenshot is done)."""
    size = parse_size(args.size)
    inputs = load_inputs(args)
    check_display()
    from rendercanvas.glfw import RenderCanvas, loop

    canvas = RenderCanvas(size=size, title=f"r360gpu viewer: {inputs[0].name}", update_mode="ondemand",
                          min_fps=2.0, max_fps=args.max_fps, vsync=False)
    app = open_viewer(args, canvas, inputs=inputs)
    shot = Path(args.screenshot) if args.screenshot else None
    state = {"requested": False}

    def draw():
        app.frame()
        if shot is None:
            return
        if state["requested"]:
            if not any(s[1] == shot for s in app.pending_screenshots()):
                canvas.close()
            return
        settled = app.frames >= SETTLE_FRAMES and app.last_scale >= 1.0 and not app.busy()
        settled = settled or app.frames >= MAX_FRAMES_BEFORE_SCREENSHOT
        if settled:
            app.request_screenshot("window", shot)
            state["requested"] = True
        app.request_draw()

    canvas.request_draw(draw)
    try:
        loop.run()
    finally:
        app.close()
    if shot is not None and not shot.is_file():
        print(f"viewer: the screenshot {shot} was not written", flush=True)
        return 1
    return 0
