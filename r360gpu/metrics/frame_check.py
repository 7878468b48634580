"""Do the cameras see the splats?  A check of pre's renders for a world-frame mismatch.

A splat scene exported in another world frame than its cameras (nerfstudio's
dataparser frame, gsplat's normalised world; :mod:`r360gpu.io.frames`)
renders mostly empty images at the evaluation views, or renders the scene
somewhere else than where the target masks say the object is.  Scoring such
a scene gives numbers that mean nothing, so the pipeline renders pre at a few
evaluation views with a visible target before scoring
(:func:`check_views`) and reads, per view:

* ``coverage``: the fraction of the image pre renders something solid in
  (alpha >= :data:`SOLID_ALPHA`);
* ``touched``: the fraction of the image pre draws anything in (alpha >
  :data:`TOUCHED_ALPHA`, one 8-bit step);
* ``target``: the fraction of the target mask's pixels pre renders something in
  (the object to remove is part of pre, so a correctly framed pre covers it);
* ``step``: the fraction of the mask's outline where pre's depth just inside
  the mask is nearer, by :data:`STEP` or more, than the farthest depth just
  outside (:func:`outline_step`): the object stands in front of what lies
  around it;

and, over the checked views, ``cones``: pre's surface under each mask,
back-projected with its camera, must lie where the masks' viewing cones
meet: the median, over ordered pairs of views (i, j), of the fraction of
view i's mask points (those that land in image j, not hidden behind pre's
surface there) that land in view j's mask (:func:`cone_agreement`).

Why the cones decide and the step only notes.  The masks and the cameras are
the only link between the cameras' world and the splats' world: pre is one 3D
model, so its renders agree with each other in any frame, and only the masks
say where the object must be.  A frame mismatch is a similarity
``x -> s R x + t`` between the worlds; the masks still mark the object in the
cameras' world, and pre's object sits wherever the similarity put it.  Pre is
right for the masks when the surface it renders under every mask is the one
3D region all the masks' viewing cones contain (the cones), and ideally ends
at the masks' outlines in front of what lies around it (the step).  The
cones stay near 1 on real scans and with masks drawn a pixel or two off; the
step does not: a flat target, a cut-out patch of a surface or masks two
pixels wide of the object's outline have little step though the frame is
right (the false alarms of the check's earlier version, which combined the
two: a real scan with its target fully covered was told its frame was
wrong).  So the cones (and the target's coverage) decide whether the
cameras miss the splats, and a low step alone is not a refusal.  What the
masks cannot tell apart: a wrong frame that puts a large surface through the
masks' 3D place (its cones high, its outline flat) looks like a flat target
framed right.  The reference tells them apart: it is pre with the object
removed, so framed right it differs from pre under the masks (``removed``
near 1, :func:`removal`), while in a wrong frame both render the same other
surface there (``removed`` near 0).  With a reference, ``removed`` is read
at the checked views whenever the coverage and the cones do not refuse
already.

Two verdicts (:func:`frame_verdict`), kept apart because they mean different things:

* ``"refuse"``, **the cameras miss the splats**: at half of the checked views or
  more pre covers less than :data:`TARGET_COVERED` of the target mask (an
  object scan on an empty background may cover 5% of the image when framed
  right, so the image's coverage alone is shown, not judged), or the
  ``cones`` are below :data:`CONES_MIN` (pre's surface under the masks is not
  where their viewing cones meet: the cameras see other splats than the masks
  mark).  Scoring would compare renders of the wrong place, so the run stops
  (:class:`~r360gpu.errors.InputError`, naming the fix).
  With a reference, the run is refused too when the median ``removed`` is
  below :data:`REMOVED_MIN`: pre and the reference render the same thing
  under the masks, so the object the reference lacks is not where the masks
  are.
* ``"note"``, **the target's outline has little depth step**: the cameras see
  the masks' object, but the median outline ``step`` is below
  :data:`STEP_NOTE`: a flat target (a poster, a patch of a surface), or masks
  drawn a few pixels off its outline; the reference, where there is one,
  lacks the object under the masks.  The check found the target where the
  masks are, so no frame advice is given; the note is kept in ``results.json``
  (without a reference, a wrong frame that puts a large surface through the
  masks' 3D place also ends here, and a rare one that puts another object
  there passes as "ok": bench/frame_check_scenes.py).
* ``"ok"`` otherwise, and when nothing was checked.

With one checked view there are no pairs (``cones`` None): only the target
rule applies.

How the thresholds were chosen: ``bench/frame_check_scenes.py`` (the table
of docs/your-scene.md, "The check") checks the demo's room and garden and the
PlayCanvas biker and guitar framed right (as they are, in gsplat's world with
the frame declared, and with masks 1-2 pixels too wide or narrow) and 100
random wrong frames per scene (a uniform rotation, a scale of 0.1-10, a
shift), each scene with its reference (pre without the target).  Framed
right, every view has the target at least 86% covered, ``cones`` is at least
0.95 and ``removed`` at least 0.83.  Of the 402 wrong frames (frame seed 1),
270 leave the target less than 80% covered at half the views, 122 have cones
of 0.87 or less, and 10 (a large surface through the masks' 3D place: cones
0.90-0.96, 9 of them with a flat outline) are told by ``removed``: 0.00-0.01,
and 0.62 for one that leaves its object 47% under its masks.  Other draws
(other demo scenes, frame seed 2; the earlier 50 per scene) are refused as
well, correct frames never.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: A pixel where pre's alpha reaches this is rendered.
SOLID_ALPHA = 0.5
#: A pixel where pre's alpha exceeds this is drawn at all.
TOUCHED_ALPHA = 1.0 / 255.0
#: Drawn fraction below this: pre renders nothing at the view (the message says so).
EMPTY = 0.01
#: Coverage below this: the view is mostly empty (shown in the message, not judged).
MOSTLY_EMPTY = 0.1
#: Target coverage below this (at half the checked views or more): the cameras miss the splats.
#: Framed right, the demo's and the PlayCanvas scenes cover the target 86-100% at every view, with
#: masks up to 2 pixels too wide (bench/frame_check_scenes.py); a wrong frame mostly 0%.
TARGET_COVERED = 0.8
#: Views checked per pre source.
CHECK_VIEWS = 4
#: What a cached verdict was computed by (part of its cache key): 3 = "refuse" / "note" / "ok",
#: 4 = the reference's removal judged too.
CHECK_VERSION = 4
#: Relative depth step at the outline that counts (:func:`outline_step`).
STEP = 0.05
#: Fewer outline (or back-projected) pixels than this: not measured.
MIN_PIXELS = 10
#: Mask points back-projected per view (an even subsample beyond).
MAX_POINTS = 4000
#: A back-projected point farther from camera j than this times pre's depth at its pixel is hidden
#: in view j (behind an occluder: it says nothing about j's mask); the slack is the STEP of the
#: outline, the depth a Gaussian's thickness and the blended outline leave.
HIDDEN = 1.0 + STEP
#: ``cones`` below this: pre's surface under the masks is not where their cones meet (refused).
#: Framed right 0.95-1.00 (masks up to 2 pixels off); the random wrong frames whose target is
#: covered 0.81 or less, but for a few at 0.90-0.97 (told by the reference, :data:`REMOVED_MIN`):
#: the threshold sits midway between 0.81 and 0.95 (bench/frame_check_scenes.py, frame seed 0).
CONES_MIN = 0.88
#: A pixel shows the removal when pre and the reference differ there by this much in a colour channel
#: or in alpha, or (both solid) by :data:`STEP` in relative depth.
DIFFERS = 0.1
#: The median ``removed`` (:func:`removal`) below this: the reference shows no removal where the masks
#: are (refused).  Framed right (masks up to 2 pixels off) the demo scenes read 1.00 and the PlayCanvas
#: scans 0.83-0.97; of the wrong frames the coverage and the cones let through, all but one 0.00-0.01,
#: the one (its object still 47% under its masks) 0.62 (bench/frame_check_scenes.py, frame seed 1).
REMOVED_MIN = 0.7
#: A view whose mask covers more of the image than this has no say in the removal: masks that hold
#: most of the picture are not an object's (a target of most of the scene, warned about where the
#: target is resolved), and the removal a reference shows is then a small part of them whatever
#: the frame.  The coverage and the cones still judge such views.
REMOVAL_MASK_MAX = 0.5
#: Median outline ``step`` below this: the target's outline has little depth step (a note).
#: Framed right with exact or 1-pixel-off masks, objects step 0.44-0.62; the guitar's cut-out target
#: (a patch of its surface) 0.00-0.08, masks 2 pixels off 0.04-0.20; the wrong frames that pass
#: CONES_MIN mostly at most 0.15, so without a reference they get the note (bench/frame_check_scenes.py).
STEP_NOTE = 0.25

LIKELY_CAUSE = (
    "the splats and the cameras are probably in different world frames: nerfstudio exports splats in its "
    "dataparser frame (put its dataparser_transforms.json beside the PLY, or set frame = \"PATH\" in scene.toml), "
    "gsplat's simple_trainer normalises the world by default (set frame = \"gsplat\" in scene.toml or pass "
    "--frame gsplat, with the COLMAP model it trained on as cameras); see docs/your-scene.md")


@dataclass(frozen=True)
class ViewCoverage:
    """What pre renders at one view: solid coverage of the image and of the target (None: empty
    target), the fraction of the image drawn at all, and the outline ``step`` fraction (None:
    not measured)."""

    view: str
    coverage: float
    target: float | None
    touched: float
    step: float | None = None


def checked_views(with_target: list[str]) -> list[str]:
    """The views checked: up to :data:`CHECK_VIEWS` of the views with a visible target, spread
    evenly over their order (views far apart see the object from different sides)."""
    if not with_target:
        return []
    idx = np.linspace(0, len(with_target) - 1, min(CHECK_VIEWS, len(with_target)))
    return list(dict.fromkeys(with_target[i] for i in idx.round().astype(int)))


def view_coverage(view: str, alpha: np.ndarray, mask: np.ndarray, depth: np.ndarray | None = None) -> ViewCoverage:
    """Coverage of the image and of the target mask by pre's rendered ``alpha`` (H, W), and with
    ``depth`` (H, W) the :func:`outline_step` fraction."""
    alpha = _alpha(alpha)
    mask = np.asarray(mask, dtype=bool)
    if alpha.shape != mask.shape:
        raise ValueError(f"alpha {alpha.shape} and mask {mask.shape} differ in size")
    solid = alpha >= SOLID_ALPHA
    n_target = int(mask.sum())
    target = float(solid[mask].sum()) / n_target if n_target else None
    if not solid.size:
        return ViewCoverage(view, 0.0, target, 0.0)
    step = None if depth is None or not n_target else outline_step(depth, alpha, mask)
    return ViewCoverage(view, float(solid.mean()), target, float((alpha > TOUCHED_ALPHA).mean()), step)


def _alpha(alpha) -> np.ndarray:
    return np.nan_to_num(np.asarray(alpha, dtype=np.float32), nan=0.0)


def _depth(depth, alpha) -> np.ndarray:
    """float64 depth where pre renders something solid and the depth is valid (finite, > 0), else NaN."""
    d = np.asarray(depth, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(d) & (d > 0) & (alpha >= SOLID_ALPHA)
    return np.where(ok, d, np.nan)


def outline_step(depth: np.ndarray, alpha: np.ndarray, mask: np.ndarray) -> float | None:
    """The fraction of the mask's outline where the object stands in front of its surroundings.

    Inner ring: mask pixels one pixel in from the outline; outer ring: pixels two pixels out.
    Of the inner-ring pixels with an outer-ring pixel within 3 pixels, the fraction where pre's
    depth is below ``(1 - STEP)`` times the farthest outer-ring depth within 3 pixels (a pixel where pre renders nothing counts as infinitely
    far: the object is in front of empty space).  Pixels where pre renders nothing solid are not
    counted inside.  None when fewer than :data:`MIN_PIXELS` inner-ring pixels are rendered.
    """
    import cv2

    alpha = _alpha(alpha)
    d = _depth(depth, alpha)
    m = np.asarray(mask, dtype=np.uint8)
    k = np.ones((3, 3), np.uint8)
    inner = (cv2.erode(m, k) > 0) & ~(cv2.erode(m, k, iterations=2) > 0) & np.isfinite(d)
    outer = (cv2.dilate(m, k, iterations=2) > 0) & ~(cv2.dilate(m, k) > 0)
    big = np.float32(np.finfo(np.float32).max)
    around = np.where(outer, np.where(np.isfinite(d), d, big), 0.0).astype(np.float32)
    window = np.ones((7, 7), np.uint8)
    farthest = cv2.dilate(around, window)
    inner &= cv2.dilate(outer.astype(np.uint8), window) > 0  # an outer-ring pixel within 3 pixels
    if inner.sum() < MIN_PIXELS:
        return None
    near = d[inner] < (1.0 - STEP) * farthest[inner].astype(np.float64)
    return float(near.mean())


def backprojected(camera, alpha: np.ndarray, depth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(N, 3) world points of pre's surface under the mask (eroded by one pixel, so the points
    are on the object rather than on its blended outline), at most :data:`MAX_POINTS` (an even
    subsample).  ``camera``: the view's :class:`~r360gpu.io.camera.Camera`, resized to the
    image if it differs; ``depth`` is z-depth in the camera's units."""
    import cv2

    alpha = _alpha(alpha)
    h, w = alpha.shape
    if (camera.width, camera.height) != (w, h):
        camera = camera.resized(w, h)
    d = _depth(depth, alpha)
    inside = (cv2.erode(np.asarray(mask, np.uint8), np.ones((3, 3), np.uint8)) > 0) & np.isfinite(d)
    rows, cols = np.nonzero(inside)
    if rows.size > MAX_POINTS:
        keep = np.linspace(0, rows.size - 1, MAX_POINTS).round().astype(np.int64)
        rows, cols = rows[keep], cols[keep]
    z = d[rows, cols]
    cam = np.stack([(cols + 0.5 - camera.cx) / camera.fx * z, (rows + 0.5 - camera.cy) / camera.fy * z, z], axis=1)
    return (cam - camera.t) @ camera.R  # R^T (x_cam - t), row-wise


def cone_agreement(views: list) -> float | None:
    """Median over ordered pairs (i, j) of views of the fraction of view i's back-projected mask
    points that land in view j's mask, among those in front of camera j, inside its image and
    not hidden there (points outside image j, or behind pre's surface in it, say nothing about
    its mask: an annotator marks only the target's visible pixels).  ``views``: [(camera,
    points (N, 3), mask (H, W)[, depth (H, W)])]; with view j's z-depth (NaN where pre renders
    nothing solid), a point farther than :data:`HIDDEN` times the depth at its pixel is hidden.
    When no pair has :data:`MIN_PIXELS` points seen in image j, the hidden points count after
    all (views that see none of each other's target surface, as opposite sides of an object
    do, still compare silhouettes).  View j's mask is widened by ``max(2, 0.5% of its longer
    side)`` pixels for the blended outline and the camera model's rounding.  None when no pair
    has :data:`MIN_PIXELS` points in image j."""
    import cv2

    widened = [_widened(mask) for _, _, mask, *_ in views]
    fractions = _cone_fractions(views, widened, hide=True) or _cone_fractions(views, widened, hide=False)
    return float(np.median(fractions)) if fractions else None


def _cone_fractions(views: list, widened: list, *, hide: bool) -> list:
    fractions = []
    for i, (_, pts, *_) in enumerate(views):
        for j, (camera, _, _, *depth) in enumerate(views):
            if i == j or not len(pts):
                continue
            h, w = widened[j].shape
            if (camera.width, camera.height) != (w, h):
                camera = camera.resized(w, h)
            x = pts @ camera.R.T + camera.t
            front = x[:, 2] > 0
            z = np.where(front, x[:, 2], 1.0)
            u, v = camera.fx * x[:, 0] / z + camera.cx, camera.fy * x[:, 1] / z + camera.cy
            seen = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
            rows, cols = v[seen].astype(np.int64), u[seen].astype(np.int64)
            if hide and depth and depth[0] is not None:
                there = np.asarray(depth[0], np.float64)[rows, cols]
                with np.errstate(invalid="ignore"):
                    shown = ~(z[seen] > HIDDEN * there)  # NaN (nothing solid there): not hidden
                rows, cols = rows[shown], cols[shown]
            if rows.size < MIN_PIXELS:
                continue
            fractions.append(float(widened[j][rows, cols].mean()))
    return fractions


def removal(pre, reference, mask: np.ndarray) -> float | None:
    """The fraction of the mask's pixels where pre and the reference differ (:data:`DIFFERS`):
    near 1 when the reference is pre with the masks' object removed, near 0 when both render the
    same surface there (the object is elsewhere).  The mask is eroded by the widening of
    :func:`cone_agreement` and one pixel more (by one pixel where that leaves nothing), so that
    masks drawn a pixel or two wide of the object count only the object.  What lies beyond the
    mask is not compared: a reference from another capture differs there by its light and its
    floaters.  ``pre``, ``reference``: the view's renders (``rgb`` (H, W, 3), ``alpha`` and
    ``depth`` (H, W), either may be None), host arrays.  None when the images differ in size or
    the mask is empty once eroded by one pixel."""
    import cv2

    m = np.asarray(mask, np.uint8)
    if np.shape(pre.rgb)[:2] != m.shape or np.shape(reference.rgb)[:2] != m.shape:
        return None
    inner = cv2.erode(m, np.ones((3, 3), np.uint8), iterations=_radius(m) + 1) > 0
    if not inner.any():
        inner = cv2.erode(m, np.ones((3, 3), np.uint8)) > 0
        if not inner.any():
            return None
    diff = np.abs(np.asarray(pre.rgb, np.float32) - np.asarray(reference.rgb, np.float32)).max(axis=-1) > DIFFERS
    if pre.alpha is not None and reference.alpha is not None:
        a, b = _alpha(pre.alpha), _alpha(reference.alpha)
        diff |= np.abs(a - b) > DIFFERS
        if pre.depth is not None and reference.depth is not None:
            da, db = _depth(pre.depth, a), _depth(reference.depth, b)
            with np.errstate(invalid="ignore"):
                diff |= np.abs(da - db) > STEP * np.fmin(da, db)  # NaN (either not solid): compares False
    return float(diff[inner].mean())


def _radius(mask: np.ndarray) -> int:
    """How far a mask is widened for the blended outline and the camera model's rounding:
    ``max(2, 0.5% of its longer side)`` pixels."""
    return max(2, int(round(0.005 * max(mask.shape))))


def _widened(mask: np.ndarray) -> np.ndarray:
    """The mask widened by :func:`_radius` pixels."""
    import cv2

    m = np.asarray(mask, np.uint8)
    r = _radius(m)
    return cv2.dilate(m, np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0


@dataclass(frozen=True)
class FrameVerdict:
    level: str  # "ok" | "note" | "refuse"
    n_views: int
    n_empty: int           # views with coverage < MOSTLY_EMPTY
    n_target_missed: int   # views whose target pre covers less than TARGET_COVERED
    views: tuple
    cones: float | None = None  # cone_agreement of the views (None: not measured)
    step: float | None = None   # median outline step of the views (None: not measured)
    removed: float | None = None  # median removal() against the reference (None: not measured)

    @property
    def missed(self) -> bool:
        """The cameras miss the splats (the run is refused)."""
        return self.level == "refuse"

    def to_dict(self) -> dict:
        d = asdict(self)
        d["views"] = [asdict(v) for v in self.views]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "FrameVerdict":
        return cls(d["level"], d["n_views"], d["n_empty"], d["n_target_missed"],
                   tuple(ViewCoverage(**v) for v in d["views"]), d.get("cones"), d.get("step"), d.get("removed"))


def frame_verdict(views: list[ViewCoverage], cones: float | None = None, removed: float | None = None) -> FrameVerdict:
    """The verdict on the checked views, their :func:`cone_agreement` and the median
    :func:`removal` against the reference (see the module docstring); "ok" when nothing was
    checked."""
    views = tuple(views)
    n_empty = sum(v.coverage < MOSTLY_EMPTY for v in views)
    with_target = [v for v in views if v.target is not None]
    n_missed = sum(v.target < TARGET_COVERED for v in with_target)
    steps = [v.step for v in views if v.step is not None]
    step = float(np.median(steps)) if steps else None
    if (with_target and 2 * n_missed >= len(with_target)) or (cones is not None and cones < CONES_MIN):
        level = "refuse"
    elif removed is not None and removed < REMOVED_MIN:
        level = "refuse"
    elif step is not None and step < STEP_NOTE:
        level = "note"
    else:
        level = "ok"
    return FrameVerdict(level, len(views), n_empty, n_missed, views, cones, step, removed)


def check_views(views: list, reference=None) -> FrameVerdict:
    """The verdict on pre's renders at the checked views: ``views`` = [(view name, camera, alpha,
    depth, mask[, rgb])] with alpha, depth (z-depth in the camera's units) and mask (H, W), rgb
    (H, W, 3).  ``reference``: None, or a function of a view name giving the reference's renders
    there (``rgb``, ``alpha``, ``depth``, host arrays; None where it has none), called at the
    views with an rgb and a mask of at most :data:`REMOVAL_MASK_MAX` of the image unless the
    coverage or the cones already refuse: the median :func:`removal` then decides too."""
    seen, cones = [], []
    for name, camera, alpha, depth, mask, *_ in views:
        seen.append(view_coverage(name, alpha, mask, depth))
        if camera is not None and depth is not None and np.asarray(mask).any():
            cones.append((camera, backprojected(camera, alpha, depth, mask), mask, _depth(depth, _alpha(alpha))))
    cones = cone_agreement(cones) if len(cones) > 1 else None
    verdict = frame_verdict(seen, cones)
    if verdict.level == "refuse" or reference is None:
        return verdict
    from types import SimpleNamespace

    removed = []
    for name, _, alpha, depth, mask, *rgb in views:
        ref = reference(name) if rgb and np.asarray(mask, bool).mean() <= REMOVAL_MASK_MAX else None
        if ref is not None:
            removed.append(removal(SimpleNamespace(rgb=rgb[0], alpha=alpha, depth=depth), ref, mask))
    removed = [r for r in removed if r is not None]
    return frame_verdict(seen, cones, float(np.median(removed)) if removed else None)


def _listed(verdict: FrameVerdict) -> str:
    return ", ".join(f"{v.view} {100 * v.coverage:.0f}%"
                     + ("" if v.target is None else f" (target {100 * v.target:.0f}%)") for v in verdict.views)


def mismatch_message(verdict: FrameVerdict, *, source: str, frame: str | None, cameras: str | None) -> str:
    """Why the cameras miss the splats, at which views, and the fix (the refusal's one line)."""
    with_target = sum(v.target is not None for v in verdict.views)
    if verdict.views and all(v.touched < EMPTY for v in verdict.views):
        what = "renders nothing"
    elif 2 * verdict.n_target_missed >= max(1, with_target):
        what = (f"covers less than {100 * TARGET_COVERED:.0f}% of the target at {verdict.n_target_missed} of "
                f"{with_target} views")
    elif verdict.cones is not None and verdict.cones < CONES_MIN:
        what = (f"renders its surface under the target masks away from where their viewing cones meet (cone "
                f"agreement {verdict.cones:.2f} < {CONES_MIN}): the cameras see other splats than the masks mark")
    else:
        what = (f"and the reference render the same thing under the target masks (they differ at "
                f"{100 * verdict.removed:.0f}% of the masks' pixels, < {100 * REMOVED_MIN:.0f}%): the object the "
                f"reference lacks is not where the masks are, or the reference still holds it")
    framed = f"the cameras were moved by {frame}" if frame else "the cameras were used as they are"
    return (f"pre ({source}) {what} at the checked evaluation views (image covered: {_listed(verdict)}; {framed}"
            f"{'' if cameras is None else f', cameras {cameras}'}): {LIKELY_CAUSE}")


def note_message(verdict: FrameVerdict) -> str:
    """The quiet note of a "note" verdict (results.json ``frame_check``): what was measured and
    what it means for the check, with no frame advice (the cameras do see the masks' object)."""
    by = ("its coverage (one view: no cones)" if verdict.cones is None
          else f"its viewing cones (cone agreement {verdict.cones:.2f})")
    by += (" only; no reference to compare with" if verdict.removed is None
           else f" and by the reference, which differs from pre at {100 * verdict.removed:.0f}% of the masks' pixels")
    return (f"the target's outline has little depth step (median {verdict.step:.2f} < {STEP_NOTE} of the outline "
            f"in front of its surroundings): a flat target, or masks a few pixels off its outline; the frame check "
            f"confirmed the target's place by {by}")
