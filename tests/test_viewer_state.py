"""The viewer's key -> state machine (pure Python, no window)."""
from __future__ import annotations

import string

import pytest

from r360gpu.viewer.state import (COLORMAPS, COMPARE_MODES, KEY_BINDINGS, Action, ViewerState, handle_key)

SCENES = ("pre", "reference", "clean", "floaters")


def press(state, *keys, mods=()):
    actions = []
    for k in keys:
        state, acts = handle_key(state, k, mods)
        actions += acts
    return state, actions


@pytest.fixture
def s0():
    return ViewerState.initial(SCENES, n_views=5)


def test_initial(s0):
    # B defaults to the reference (what a method is compared against), pre without one
    assert (s0.name_a, s0.name_b, s0.compare) == ("pre", "reference", "none")
    assert ViewerState.initial(["pre", "clean", "floaters"], 2).name_b == "pre"
    assert s0.shown() == ("pre",) and s0.view_index == 0 and s0.on_view
    assert ViewerState.initial(["pre"], 0).view_index is None
    with pytest.raises(ValueError):
        ViewerState.initial([], 3)


def test_digits_pick_scenes(s0):
    s, _ = press(s0, "3")
    assert s.name_a == "clean"
    s, _ = press(s, "2", mods=("Shift",))
    assert s.name_b == "reference" and s.name_a == "clean"
    s, _ = press(s, "@")  # Shift+2 on a US layout
    assert s.name_b == "reference"
    assert press(s, "9")[0] == s  # no ninth scene: unchanged
    s, _ = press(s, "t")
    assert (s.name_a, s.name_b) == ("reference", "clean")


def test_compare_modes_cycle(s0):
    seen = []
    s = s0
    for _ in COMPARE_MODES:
        s, _ = press(s, "Tab")
        seen.append(s.compare)
    assert seen == ["side", "wipe", "none"]
    s, _ = press(s0, "Tab")
    assert s.shown() == ("pre", "reference")
    assert s.with_wipe(1.7).wipe == 1.0 and s.with_wipe(-1).wipe == 0.0


def test_overlay_keys(s0):
    s, _ = press(s0, "z", "x", "v", "n")
    ov = s.overlays
    assert ov.depth and ov.delta_heat and ov.changed and ov.probes and ov.any_delta()
    s, _ = press(s, "b")
    assert not s.overlays.outline  # on by default, toggled off
    s, _ = press(s, "x", "v")
    assert not s.overlays.any_delta()
    s, _ = press(s0, *["m"] * len(COLORMAPS))
    assert s.overlays.colormap == COLORMAPS[0]
    s, _ = press(s0, "m")
    assert s.overlays.colormap == COLORMAPS[1]
    s, _ = press(s0, *["]"] * 10)
    assert s.overlays.opacity == 1.0
    s, _ = press(s, *["["] * 3)
    assert s.overlays.opacity == pytest.approx(0.7)
    with pytest.raises(ValueError):
        s0.with_overlays(colormap="jet")


def test_held_movement_keys(s0):
    s, acts = handle_key(s0, "w", ())
    s, _ = handle_key(s, "d", ("Shift",))
    assert acts == () and s.movement() == (1, 1, 0)
    s, _ = handle_key(s, "S", ("Shift",))  # capital with Shift is the same key
    assert s.movement() == (0, 1, 0)
    s, _ = handle_key(s, "e", ())
    s, _ = handle_key(s, "d", (), down=False)
    assert s.movement() == (0, 0, 1)
    for k in "wse":
        s, _ = handle_key(s, k, (), down=False)
    assert s.movement() == (0, 0, 0) and s.held == frozenset()


def test_view_stepping(s0):
    s, acts = press(s0, "ArrowRight")
    assert acts == [Action("view", 1)] and s.view_index == 1 and s.on_view
    s, acts = press(s, ",", ",")
    assert acts[-1] == Action("view", 4)  # wraps around
    s = s.moved()
    s, acts = press(s, "ArrowLeft")
    assert acts == [Action("view", 4)]  # off the path: back returns to the last view
    s, acts = press(s.moved(), ".")
    assert acts == [Action("view", 0)]
    s, acts = press(s, " ")
    assert acts == [Action("snap")]
    none = ViewerState.initial(SCENES, 0)
    assert press(none, "ArrowRight", " ")[1] == []


def test_camera_and_capture_actions(s0):
    s, acts = press(s0, "g")
    assert s.camera_mode == "fly" and acts == []
    s, acts = press(s, "r", "f", "u", "l", "-", "=")
    assert [a.kind for a in acts] == ["reset", "focus", "up", "level", "fov", "fov"]
    assert acts[4].arg > 0 > acts[5].arg
    assert not s.on_view  # reset / focus / up / level leave the evaluation view
    _, acts = press(s0, "p")
    assert acts == [Action("screenshot", "view")]
    _, acts = press(s0, "P", mods=("Shift",))
    assert acts == [Action("screenshot", "window")]
    s, acts = press(s0, "k")
    assert s.recording and acts == [Action("record", True)]
    s, acts = press(s, "k")
    assert not s.recording and acts == [Action("record", False)]
    s, _ = press(s0, "i", "h")
    assert not s.show_ui and s.show_help
    s, _ = press(s, "F1")
    assert not s.show_help


def test_unknown_keys_and_releases_do_nothing(s0):
    for key in ("y", "F7", "~"):
        assert handle_key(s0, key, ()) == (s0, ())
    assert handle_key(s0, "j", ()) == (s0, (Action("worst"),))  # J: worst view (the app picks it)
    assert handle_key(s0, "Tab", (), down=False) == (s0, ())


def test_escape_and_q_close_c_moves_down(s0):
    for key in ("Escape", "q", "Q"):
        assert handle_key(s0, key, ()) == (s0, (Action("quit"),))
        assert handle_key(s0, key, (), down=False) == (s0, ())
    s, acts = handle_key(s0, "c", ())
    assert acts == () and s.movement() == (0, 0, -1)


def test_every_letter_key_is_documented(s0):
    documented = " ".join(k for k, _ in KEY_BINDINGS).upper()
    tokens = set(documented.replace("/", " ").replace(",", " ").split())
    for letter in string.ascii_lowercase:
        if handle_key(s0, letter, ()) != (s0, ()):
            assert letter.upper() in tokens, f"key {letter!r} does something but is not in KEY_BINDINGS"
