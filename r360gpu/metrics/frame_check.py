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
view i's mask points (those that land in image j) that land in view j's mask
(:func:`cone_agreement`).

Why these two, and why together (the argument the tests check on the whole
class of mismatches).  The masks and the cameras are the only link between
the cameras' world and the splats' world: pre is one 3D model, so its renders
agree with each other in any frame, and only the masks say where the object
must be.  A frame mismatch is a similarity ``x -> s R x + t`` between the
worlds; the masks still mark the object in the cameras' world, and pre's
object sits wherever the similarity put it.  Pre is right for the masks when
the surface it renders under every mask (a) is the one 3D region all the
masks' viewing cones contain, and (b) ends at the masks' outlines, in front
of what lies around it.  Each condition alone can hold by chance: far
geometry under the masks of views a few tens of degrees apart projects back
into the others' masks (a), and a scene full of depth steps (trees, a
cluttered room) puts steps on any outline (b).  But (a) and (b) together
mean there is, at the masks' 3D place, something that occupies their cones
and whose silhouette is theirs: the object, where the masks are.  A
mismatch that leaves this true (a turn about the object's own centre that
keeps its silhouettes, within its symmetry) is one the masks still fit, and
the scores then still measure the object's removal.  The two are combined
as the geometric mean ``agreement = sqrt(cones * median step)``: one low
factor pulls it down, and neither alone can carry it.

With one checked view there are no pairs (``cones`` None): only the coverage
rules apply.  A flat target (a poster on a wall) has no depth step along its
outline, so it is warned about without cause.

Verdict (:func:`frame_verdict`):

* ``"refuse"``: at every checked view pre draws anything in less than
  :data:`EMPTY` of the image: the cameras look at nothing;
* ``"warn"``: at half of the checked views or more, pre covers less than
  :data:`MOSTLY_EMPTY` of the image, or less than :data:`TARGET_COVERED` of the
  target; or ``agreement`` is below :data:`AGREEMENT_MIN`;
* ``"ok"`` otherwise.

Measured (tests/test_frame_check_class.py generates the class: 24 random
similarities, gsplat's normalisation with and without its half turn and
nerfstudio's dataparser transform applied to the splats of the demo's room
and garden at 128x96): correctly framed scenes have ``agreement`` 0.72-0.75,
and every mismatched one (the object's silhouette overlapping its masks by
IoU < 0.5: 53 of 53) is flagged, at most 0.56.  The demo's scenes at their
own size (480x360, 16 views): 0.74 (room) and 0.85 (garden); in gsplat's
world with the cameras as they are, 0.00 and 0.23.  :data:`AGREEMENT_MIN`
lies between the two groups.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: A pixel where pre's alpha reaches this is rendered.
SOLID_ALPHA = 0.5
#: A pixel where pre's alpha exceeds this is drawn at all.
TOUCHED_ALPHA = 1.0 / 255.0
#: Drawn fraction below this: pre renders nothing at the view.
EMPTY = 0.01
#: Coverage below this: the view is mostly empty.
MOSTLY_EMPTY = 0.1
#: Target coverage below this: the target mask falls where pre renders little.
TARGET_COVERED = 0.5
#: Views checked per pre source.
CHECK_VIEWS = 4
#: What a cached verdict was computed by (part of its cache key): 2 = cone agreement and outline step.
CHECK_VERSION = 2
#: Relative depth step at the outline that counts (:func:`outline_step`).
STEP = 0.05
#: Fewer outline (or back-projected) pixels than this: not measured.
MIN_PIXELS = 10
#: Mask points back-projected per view (an even subsample beyond).
MAX_POINTS = 4000
#: ``agreement`` below this: pre's surface under the masks is not the object the masks outline.
AGREEMENT_MIN = 0.64

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
    points that land in view j's mask, among those in front of camera j and inside its image
    (points outside image j say nothing).  ``views``: [(camera, points (N, 3), mask (H, W))].
    View j's mask is widened by ``max(2, 0.5% of its longer side)`` pixels for the blended
    outline and the camera model's rounding.  None when no pair has :data:`MIN_PIXELS` points
    in image j."""
    import cv2

    fractions = []
    widened = []
    for camera, _, mask in views:
        m = np.asarray(mask, np.uint8)
        r = max(2, int(round(0.005 * max(m.shape))))
        widened.append(cv2.dilate(m, np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0)
    for i, (_, pts, _) in enumerate(views):
        for j, (camera, _, mask) in enumerate(views):
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
            if seen.sum() < MIN_PIXELS:
                continue
            fractions.append(float(widened[j][v[seen].astype(np.int64), u[seen].astype(np.int64)].mean()))
    return float(np.median(fractions)) if fractions else None


@dataclass(frozen=True)
class FrameVerdict:
    level: str  # "ok" | "warn" | "refuse"
    n_views: int
    n_empty: int           # views with coverage < MOSTLY_EMPTY
    n_target_missed: int   # views whose target pre covers less than TARGET_COVERED
    views: tuple
    cones: float | None = None      # cone_agreement of the views (None: not measured)
    agreement: float | None = None  # sqrt(cones * median step) (None: not measured)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["views"] = [asdict(v) for v in self.views]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "FrameVerdict":
        return cls(d["level"], d["n_views"], d["n_empty"], d["n_target_missed"],
                   tuple(ViewCoverage(**v) for v in d["views"]), d.get("cones"), d.get("agreement"))


def frame_verdict(views: list[ViewCoverage], cones: float | None = None) -> FrameVerdict:
    """The verdict on the checked views and their :func:`cone_agreement` (see the module
    docstring); "ok" when nothing was checked."""
    views = tuple(views)
    n = len(views)
    n_empty = sum(v.coverage < MOSTLY_EMPTY for v in views)
    with_target = [v for v in views if v.target is not None]
    n_missed = sum(v.target < TARGET_COVERED for v in with_target)
    if n and all(v.touched < EMPTY for v in views):
        level = "refuse"
    elif n and (2 * n_empty >= n or (with_target and 2 * n_missed >= len(with_target))):
        level = "warn"
    else:
        level = "ok"
    steps = [v.step for v in views if v.step is not None]
    agreement = None
    if cones is not None and steps:
        agreement = float(np.sqrt(cones * float(np.median(steps))))
    if level == "ok" and agreement is not None and agreement < AGREEMENT_MIN:
        level = "warn"
    return FrameVerdict(level, n, n_empty, n_missed, views, cones, agreement)


def check_views(views: list) -> FrameVerdict:
    """The verdict on pre's renders at the checked views: ``views`` = [(view name, camera, alpha,
    depth, mask)] with alpha, depth (z-depth in the camera's units) and mask (H, W)."""
    seen, cones = [], []
    for name, camera, alpha, depth, mask in views:
        seen.append(view_coverage(name, alpha, mask, depth))
        if camera is not None and depth is not None and np.asarray(mask).any():
            cones.append((camera, backprojected(camera, alpha, depth, mask), mask))
    return frame_verdict(seen, cone_agreement(cones) if len(cones) > 1 else None)


def mismatch_message(verdict: FrameVerdict, *, source: str, frame: str | None, cameras: str | None) -> str:
    """What went wrong, at which views, and the likely cause (for the error or the warning)."""
    listed = ", ".join(f"{v.view} {100 * v.coverage:.0f}%"
                       + ("" if v.target is None else f" (target {100 * v.target:.0f}%)") for v in verdict.views)
    with_target = sum(v.target is not None for v in verdict.views)
    what = ("renders nothing" if verdict.level == "refuse" else
            "renders mostly empty images" if 2 * verdict.n_empty >= verdict.n_views else
            "renders little where the target masks are" if 2 * verdict.n_target_missed >= max(1, with_target) else
            f"renders no object where the target masks are (agreement {verdict.agreement:.2f} < {AGREEMENT_MIN}: "
            f"its surface under the masks is not where their viewing cones meet, or does not stand out at their "
            f"outlines)")
    framed = f"the cameras were moved by {frame}" if frame else "the cameras were used as they are"
    return (f"pre ({source}) {what} at the checked evaluation views (image covered: {listed}; {framed}"
            f"{'' if cameras is None else f', cameras {cameras}'}): {LIKELY_CAUSE}")
