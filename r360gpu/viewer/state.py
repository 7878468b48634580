"""The viewer's state machine: pure Python, no window, no GPU.

A :class:`ViewerState` is immutable; :func:`handle_key` maps (state, key
event) to a new state plus a tuple of :class:`Action` requests that the app
carries out (camera moves, screenshots).  Everything the user can switch with
a key lives here, so tests drive the viewer's logic without a window.

Scenes are named by their position in :attr:`ViewerState.scenes`: ``pre``
first, then ``reference`` when the bundle has one, then every method in the
bundle's order.  Scene A is what a single view shows; side-by-side and wipe
show A (left) and B (right).

Key names follow rendercanvas' events (``"a"``, ``"A"`` with Shift,
``"ArrowLeft"``, ``"Tab"``, ``" "``); modifiers are the strings ``"Shift"``,
``"Control"``, ``"Alt"``, ``"Meta"``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

#: Comparison layouts, in the order the Tab key cycles them.
COMPARE_MODES = ("none", "side", "wipe")
#: Colour maps of the depth and |dD| overlays (see :mod:`r360gpu.viewer.colormaps`).
COLORMAPS = ("turbo", "viridis", "inferno", "gray")
#: Overlay switches and the key toggling each.
OVERLAY_KEYS = {"z": "depth", "x": "delta_heat", "v": "changed", "b": "outline", "n": "probes", "o": "residuals"}
#: Movement keys -> (forward, right, up) unit steps.
#: (Q closes the window, so down is C.)
MOVE_KEYS = {"w": (1, 0, 0), "s": (-1, 0, 0), "d": (0, 1, 0), "a": (0, -1, 0), "e": (0, 0, 1), "c": (0, 0, -1)}
#: Keys that close the window.
QUIT_KEYS = ("Escape", "q", "Q")
#: US-layout characters of Shift + digit, accepted as the digit with Shift.
_SHIFTED_DIGITS = {"!": "1", "@": "2", "#": "3", "$": "4", "%": "5", "^": "6", "&": "7", "*": "8", "(": "9"}
#: Opacity change per [ / ] press.
OPACITY_STEP = 0.1
#: Field-of-view change per - / = press (degrees).
FOV_STEP = 5.0

#: (keys, what they do), for the help panel and docs/viewer.md (checked equal by tests/test_docs_build.py).
KEY_BINDINGS = (
    ("1 .. 9", "show scene n as A (1 = pre, then reference if any, then the methods)"),
    ("Shift + 1 .. 9", "make scene n the B side of the comparison (default: the reference, else pre)"),
    ("T", "swap A and B"),
    ("Tab", "comparison: single -> side by side -> A/B wipe (drag the wipe line with the left mouse button)"),
    ("Left mouse drag", "orbit around the pivot (orbit mode) / look around (fly mode)"),
    ("Right / middle mouse drag", "pan (also Shift + left drag)"),
    ("Mouse wheel", "zoom to the pivot (orbit) / step forward (fly)"),
    ("W A S D", "move forward / left / back / right"),
    ("C / E", "move down / up along the world up axis"),
    ("Shift / Control (held)", "move 4x faster / 4x slower"),
    ("G", "switch orbit / fly camera"),
    ("R", "reset the camera"),
    ("F", "focus on the target object"),
    ("- / =", "widen / narrow the field of view"),
    ("U", "camera up-axis fix: cycle the world up axis (auto, -y, +y, +z, -z, +x, -x) and level"),
    ("L", "level the camera (remove roll)"),
    ("Left / Right or , / .", "previous / next evaluation camera"),
    ("Space", "snap to the closest evaluation camera"),
    ("J", "jump to scene A's worst evaluation view (lowest mean of its per-view axes in the results file)"),
    ("Z", "overlay: depth of each shown scene"),
    ("X", "overlay: |dD| heat map against pre (dimmed below the GHT threshold)"),
    ("V", "overlay: changed mask (|dD| above the GHT threshold)"),
    ("B", "overlay: target mask outline (at evaluation views)"),
    ("N", "overlay: probe masks (when cached for the view)"),
    ("O", "residual highlight: colour a method's Gaussians by their residual (score --residuals; "
          "view --results, or a residuals PLY as the method)"),
    ("M", "next colour map"),
    ("[ / ]", "overlay opacity down / up"),
    ("P", "screenshot of the view (PNG); Shift + P: the whole window with the panels"),
    ("K", "start / stop recording the camera path to images"),
    ("I", "show / hide the panels"),
    ("H or F1", "show / hide this help"),
    ("Esc or Q", "close the window"),
)


@dataclass(frozen=True)
class Action:
    """A request for the app: ``kind`` plus an optional argument.

    kinds: "view" (arg: evaluation view index to jump to), "snap" (to the
    closest evaluation camera), "reset", "focus", "fov" (arg: degrees to
    add), "up" (cycle the up axis), "level", "screenshot" (arg: "view" or
    "window"), "record" (arg: True to start, False to stop), "quit" (close
    the window).
    """

    kind: str
    arg: object = None


@dataclass(frozen=True)
class Overlays:
    """Overlay switches and their display settings.

    depth_range / delta_range: (lo, hi) in scene units used when the
    matching ``*_auto`` is False; auto ranges come from the current image.
    opacity in [0, 1] scales every overlay.
    """

    depth: bool = False
    delta_heat: bool = False  # the |dD| heat map (OverlaySettings.delta holds its statistics)
    changed: bool = False
    outline: bool = True
    probes: bool = False
    residuals: bool = False  # the method's Gaussians coloured by their residual (viewer.residuals)
    colormap: str = "turbo"
    opacity: float = 0.6
    depth_auto: bool = True
    depth_range: tuple[float, float] = (0.0, 1.0)
    delta_auto: bool = True
    delta_range: tuple[float, float] = (0.0, 1.0)

    def any_delta(self) -> bool:
        """Whether an overlay needs the depth change against pre."""
        return self.delta_heat or self.changed


@dataclass(frozen=True)
class ViewerState:
    """Everything switchable in the viewer (immutable; see :func:`handle_key`).

    scenes: scene names; scene_a / scene_b: indices into it.
    compare: one of :data:`COMPARE_MODES`; wipe: the wipe line's position as
        a fraction of the view width, in [0, 1].
    n_views: number of evaluation views; view_index: the last evaluation view
        visited (None before any); on_view: whether the camera is on it now.
    camera_mode: "orbit" or "fly"; held: movement keys held down (lower case).
    show_ui / show_help: panels and the key-binding window; recording: a
        camera-path recording is running.
    """

    scenes: tuple[str, ...]
    scene_a: int = 0
    scene_b: int = 0
    compare: str = "none"
    wipe: float = 0.5
    overlays: Overlays = field(default_factory=Overlays)
    n_views: int = 0
    view_index: int | None = None
    on_view: bool = False
    camera_mode: str = "orbit"
    held: frozenset = frozenset()
    show_ui: bool = True
    show_help: bool = False
    recording: bool = False

    @classmethod
    def initial(cls, scenes, n_views: int, *, on_view: bool = True) -> "ViewerState":
        """Start on scene 0 (pre) as A and the reference as B (pre when there is none): what a
        method is compared against; at view 0."""
        scenes = tuple(str(s) for s in scenes)
        if not scenes:
            raise ValueError("the viewer needs at least one scene")
        has_view = n_views > 0 and on_view
        return cls(scenes=scenes, scene_a=0, scene_b=scenes.index("reference") if "reference" in scenes else 0,
                   n_views=int(n_views), view_index=0 if n_views > 0 else None, on_view=has_view)

    # -- derived ------------------------------------------------------------
    @property
    def name_a(self) -> str:
        return self.scenes[self.scene_a]

    @property
    def name_b(self) -> str:
        return self.scenes[self.scene_b]

    def shown(self) -> tuple[str, ...]:
        """The scenes on screen: (A,) alone, or (A, B) when comparing."""
        return (self.name_a,) if self.compare == "none" else (self.name_a, self.name_b)

    def movement(self) -> tuple[int, int, int]:
        """(forward, right, up) in {-1, 0, 1} from the held movement keys."""
        f = r = u = 0
        for k in self.held:
            df, dr, du = MOVE_KEYS[k]
            f, r, u = f + df, r + dr, u + du
        return (max(-1, min(1, f)), max(-1, min(1, r)), max(-1, min(1, u)))

    # -- transitions --------------------------------------------------------
    def with_scene(self, side: str, index: int) -> "ViewerState":
        """Scene ``index`` on side "a" or "b" (out-of-range indices leave the state unchanged)."""
        if not 0 <= index < len(self.scenes):
            return self
        return replace(self, scene_a=index) if side == "a" else replace(self, scene_b=index)

    def with_overlays(self, **changes) -> "ViewerState":
        ov = replace(self.overlays, **changes)
        if ov.colormap not in COLORMAPS:
            raise ValueError(f"colour map must be one of {COLORMAPS}, got {ov.colormap!r}")
        ov = replace(ov, opacity=float(min(1.0, max(0.0, ov.opacity))))
        return replace(self, overlays=ov)

    def with_wipe(self, fraction: float) -> "ViewerState":
        return replace(self, wipe=float(min(1.0, max(0.0, fraction))))

    def at_view(self, index: int) -> "ViewerState":
        """The camera is now on evaluation view ``index``."""
        if not 0 <= index < self.n_views:
            raise IndexError(f"view index {index} out of range for {self.n_views} views")
        return replace(self, view_index=int(index), on_view=True)

    def moved(self) -> "ViewerState":
        """The camera left the evaluation view it was on."""
        return replace(self, on_view=False) if self.on_view else self

    def step_target(self, step: int) -> int | None:
        """The evaluation view ``step`` away from the current one (wrapping), None without views.

        On a view: the neighbour in the evaluation order.  Off a view: back
        returns to the last view visited, forward goes to the one after it.
        Before any view was visited: forward goes to 0, back to the last.
        """
        if self.n_views == 0:
            return None
        if self.view_index is None:
            return 0 if step > 0 else self.n_views - 1
        if not self.on_view and step < 0:
            return self.view_index  # back to where we left the path
        return (self.view_index + step) % self.n_views


def _digit(key: str) -> str | None:
    key = _SHIFTED_DIGITS.get(key, key)
    return key if len(key) == 1 and key in "123456789" else None


def handle_key(state: ViewerState, key: str, modifiers=(), *, down: bool = True) -> tuple[ViewerState, tuple[Action, ...]]:
    """The new state and the app actions for one key event.

    ``down``: key press (True) or release (False); releases only matter for
    the held movement keys.  Unknown keys leave the state unchanged.
    """
    mods = set(modifiers)
    if key in QUIT_KEYS:
        return state, (Action("quit"),) if down else ()
    if key in _SHIFTED_DIGITS:
        mods.add("Shift")
    low = key.lower() if len(key) == 1 else key
    if low in MOVE_KEYS:
        held = state.held | {low} if down else state.held - {low}
        return replace(state, held=frozenset(held)), ()
    if not down:
        return state, ()
    s, ov = state, state.overlays
    digit = _digit(key)
    if digit is not None:
        return s.with_scene("b" if "Shift" in mods else "a", int(digit) - 1), ()
    if low == "t":
        return replace(s, scene_a=s.scene_b, scene_b=s.scene_a), ()
    if key == "Tab":
        i = COMPARE_MODES.index(s.compare)
        return replace(s, compare=COMPARE_MODES[(i + 1) % len(COMPARE_MODES)]), ()
    if low in OVERLAY_KEYS:
        name = OVERLAY_KEYS[low]
        return s.with_overlays(**{name: not getattr(ov, name)}), ()
    if low == "m":
        i = COLORMAPS.index(ov.colormap)
        return s.with_overlays(colormap=COLORMAPS[(i + 1) % len(COLORMAPS)]), ()
    if key == "[":
        return s.with_overlays(opacity=round(ov.opacity - OPACITY_STEP, 6)), ()
    if key == "]":
        return s.with_overlays(opacity=round(ov.opacity + OPACITY_STEP, 6)), ()
    if low == "g":
        return replace(s, camera_mode="fly" if s.camera_mode == "orbit" else "orbit"), ()
    if low == "r":
        return s.moved(), (Action("reset"),)
    if low == "f":
        return s.moved(), (Action("focus"),)
    if key == "-":
        return s, (Action("fov", FOV_STEP),)
    if key in ("=", "+"):
        return s, (Action("fov", -FOV_STEP),)
    if low == "u":
        return s.moved(), (Action("up"),)
    if low == "l":
        return s.moved(), (Action("level"),)
    if key in ("ArrowLeft", ",", "ArrowRight", "."):
        target = s.step_target(-1 if key in ("ArrowLeft", ",") else 1)
        if target is None:
            return s, ()
        return s.at_view(target), (Action("view", target),)
    if key == " ":
        return s, (Action("snap"),) if s.n_views else ()
    if low == "j":
        return s, (Action("worst"),) if s.n_views else ()
    if low == "p":
        return s, (Action("screenshot", "window" if ("Shift" in mods or key == "P") else "view"),)
    if low == "k":
        return replace(s, recording=not s.recording), (Action("record", not s.recording),)
    if low == "i":
        return replace(s, show_ui=not s.show_ui), ()
    if low == "h" or key == "F1":
        return replace(s, show_help=not s.show_help), ()
    return s, ()
